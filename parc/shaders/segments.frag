#version 430
// Ray distance t of this pixel's centre ray to the face, in float64.
//
// The ray is the caster's own (raycast/rays.py): the screen offsets sx, sy
// come from a table computed by the caster's formula in float64, and the
// direction D = f + tan(fov/2) (sx r + sy u) is formed in the same order,
// `precise` so no fused multiply-add changes its rounding. The crossing
// with the face's plane is found with the unnormalized D (same point) and
// kept only if it lies on the face, within a tolerance far below a cell;
// only then is t scaled to unit speed. Output (t, -t) under MIN blending
// gives each pixel's smallest and largest t in one pass.
layout(std430, binding = 1) readonly buffer ScreenOffsets { double sxy[]; };  // sx[0..W), sy[0..H)

uniform dvec3 eye;
uniform dvec3 fwd;
uniform dvec3 right;
uniform dvec3 upv;
uniform int parallel;
uniform double tan_half;
uniform double pscale;
uniform int width;
uniform double scale;        // coordinate and distance scale of the scene
uniform double tol_rel;      // face test tolerance: tol_rel * (scale + |t|)
uniform double t_min;        // crossings before this are behind the ray start

flat in int g_axis;
flat in double g_plane;
flat in dvec4 g_rect;

layout(location = 0) out vec2 frag;

void main() {
    int x = int(gl_FragCoord.x);
    int y = int(gl_FragCoord.y);
    double sx = sxy[x];
    double sy = sxy[width + y];
    precise dvec3 o;
    precise dvec3 d;
    if (parallel != 0) {
        o = eye + pscale * (sx * right + sy * upv);
        d = fwd;
    } else {
        o = eye;
        d = fwd + tan_half * (sx * right + sy * upv);
    }
    // Components along the face's axis a and its spanning axes u, v
    // (selects, not dynamic indexing: cheaper on llvmpipe).
    int a = g_axis;
    double da = a == 0 ? d.x : (a == 1 ? d.y : d.z);
    double oa = a == 0 ? o.x : (a == 1 ? o.y : o.z);
    dvec2 duv = a == 0 ? d.yz : (a == 1 ? d.zx : d.xy);
    dvec2 ouv = a == 0 ? o.yz : (a == 1 ? o.zx : o.xy);
    // A ray exactly parallel to the face never needs it: where such a ray
    // enters or leaves the PC region it crosses another outer face whose
    // axis it is not parallel to (a face perpendicular to the entering
    // axis, or the side face where a PC neighbour meets an empty diagonal
    // one). Nearly parallel rays need no special case: D is the caster's
    // direction to the last bit, so the crossing is as accurate as for
    // any ray (each rounding is relative to the quantity rounded), and a
    // far-off crossing simply fails the face test.
    if (da == 0.0) discard;
    precise double s = (g_plane - oa) / da;
    precise double t = parallel != 0 ? s : s * sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    if (t < t_min) discard;
    double tol = tol_rel * (scale + abs(t));
    precise double pu = ouv.x + s * duv.x;
    precise double pv = ouv.y + s * duv.y;
    // Written so that NaN or inf (a crossing at infinity) fails and discards.
    if (!(pu >= g_rect.x - tol && pu <= g_rect.y + tol && pv >= g_rect.z - tol && pv <= g_rect.w + tol))
        discard;
    frag = vec2(float(t), float(-t));
}
