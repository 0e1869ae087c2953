#version 430
// OR this face's plane bits into the pixel's words, if the pixel-centre ray
// may cross the face (compiled with PARALLEL defined for parallel views).
//
// The crossing point p (relative to the eye, in the face's spanning axes
// u, v) is found as in segments.frag from three affine forms of the pixel
// indices (see bitplanes.geom): perspective p = (w / d_a) (d_u, d_v),
// parallel p = the forms themselves. The fragment is discarded only when p
// lies outside the face's rectangle grown by p's error bound (or is NaN)
// and the bound is valid; otherwise the face's bits are ORed in: a
// three-plane window starting at plane `g_info.y` (relative to the first
// plane), with the bits of `g_info.z` always set and, for faces parallel to the plane
// axis in halo mode, the planes below / above set when p's coordinate
// along the plane axis lies within `g_thr` of the face's slab ends.
// Bits outside [0, count) are dropped. No colour is written: the words
// live in a shader storage buffer laid out as the caster reads them,
// bits[(y * width + x) * nwords + word].
flat in vec3 g_b;
flat in vec3 g_c;
flat in vec3 g_a;
flat in float g_w;
flat in vec4 g_rect;
flat in ivec4 g_info;        // (test, base, mask, cond)
flat in vec2 g_thr;

layout(std430, binding = 1) buffer Bits { uint bits[]; };
uniform int width;
uniform int nwords;
uniform int count;

void main() {
    vec2 c = floor(gl_FragCoord.xy);          // pixel indices, exact
    precise float kb = g_b.x + g_b.y * c.x + g_b.z * c.y;
    precise float kc = g_c.x + g_c.y * c.x + g_c.z * c.y;
#ifdef PARALLEL
    vec2 p = vec2(kb, kc);
#else
    precise float ka = g_a.x + g_a.y * c.x + g_a.z * c.y;
    precise float r = g_w / ka;
    precise vec2 p = r * vec2(kb, kc);
#endif
    bool test = g_info.x != 0;
    bool inside = p.x >= g_rect.x && p.x <= g_rect.y && p.y >= g_rect.z && p.y <= g_rect.w;
    if (test && !inside) discard;             // NaN is outside
    uint m = uint(g_info.z);
    int cond = g_info.w;
    if (cond != 0) {
        float pa = (cond & 4) != 0 ? p.y : p.x;
        bool force = !test;
        if ((cond & 1) != 0 && (force || !(pa > g_thr.x))) m |= 1u;
        if ((cond & 2) != 0 && (force || !(pa < g_thr.y))) m |= 4u;
    }
    int q = g_info.y;
    if (q < 0) {                              // the window starts below the first plane
        m = q >= -2 ? m >> uint(-q) : 0u;
        q = 0;
    }
    int room = count - q;
    if (room < 3) m &= room > 0 ? (1u << uint(room)) - 1u : 0u;
    if (m == 0u) discard;
    int base = (int(c.y) * width + int(c.x)) * nwords;
    int word = q >> 5;
    int s = q & 31;
    atomicOr(bits[base + word], m << uint(s));
    if (s > 29) {
        uint rest = m >> uint(32 - s);
        if (rest != 0u) atomicOr(bits[base + word + 1], rest);
    }
}
