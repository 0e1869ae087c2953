#version 430
// Conservative bounds on the ray distance t of this pixel's centre ray to
// the face, in float32 (compiled with PARALLEL defined for parallel views).
//
// The ray is the caster's (raycast/rays.py). Over pixel indices (x, y) the
// geometry shader hands three affine forms k0 + kx x + ky y per face:
//   perspective: the ray direction's components d_a, d_u, d_v along the
//     face's axis and spanning axes; the crossing is r d with r = w / d_a
//     (w = plane - eye_a), so p = r (d_u, d_v) relative to the eye and
//     t = r |d| at unit speed;
//   parallel: t and the crossing point p directly (affine in a parallel
//     view).
// and bounds that hold for every ray really crossing the face (raster.py,
// "Error bounds"): the rectangle, grown by p's error bound, and
// |t32 - t| <= e_abs + e_rel |t32|. A fragment whose p is outside the
// grown rectangle (or NaN) cannot belong to a crossing ray and is
// discarded; otherwise it writes near t - e and far t + e. Faces flagged
// by the geometry shader write the face's own range of t instead. Output
// (max(near, 0), -far) under MIN blending gives each pixel's smallest near
// and largest far in one pass; a far below 0 (a crossing behind the ray's
// start) is discarded.
flat in vec3 g_a;            // perspective: d_a, d_u, d_v; parallel: t, p_u, p_v
flat in vec3 g_b;
flat in vec3 g_c;
flat in float g_w;           // perspective: plane - eye_a
flat in vec4 g_rect;         // (u0, u1, v0, v1) - eye, grown
flat in vec2 g_err;          // (e_abs, e_rel), or (-1 or -2, _): write the t range
flat in vec2 g_trange;       // t on the face lies in [x, y]

layout(location = 0) out vec2 frag;

void main() {
    vec2 c = floor(gl_FragCoord.xy);          // pixel indices, exact
    precise float ka = g_a.x + g_a.y * c.x + g_a.z * c.y;
    precise float kb = g_b.x + g_b.y * c.x + g_b.z * c.y;
    precise float kc = g_c.x + g_c.y * c.x + g_c.z * c.y;
#ifdef PARALLEL
    precise float t = ka;
    vec2 p = vec2(kb, kc);
#else
    precise float r = g_w / ka;
    precise vec2 p = r * vec2(kb, kc);
#endif
    bool inside = p.x >= g_rect.x && p.x <= g_rect.y && p.y >= g_rect.z && p.y <= g_rect.w;
    if (!inside && g_err.x > -1.5) discard;   // NaN is outside
#ifndef PARALLEL
    precise float t = r * sqrt(ka * ka + kb * kb + kc * kc);
#endif
    precise float e = g_err.x + g_err.y * abs(t);
    bool range = g_err.x < 0.0;
    float nearc = range ? g_trange.x : t - e;
    float farc = range ? g_trange.y : t + e;
    if (farc < 0.0) discard;
    frag = vec2(max(nearc, 0.0), -farc);
}
