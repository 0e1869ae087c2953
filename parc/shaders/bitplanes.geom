#version 430
// Conservative coverage of one plane-proxy face, and its constants for the
// fragment shader: the bit-plane counterpart of segments.geom.
//
// The geometry is segments.geom's (kept in step with it): the face's
// corners in float64 from the boundary table, clipped against "forward
// distance >= clip_near", projected, and grown to contain the Minkowski
// sum with the pad rectangle (the bounding box for clipped, off-screen or
// degenerate faces), so every pixel whose centre ray crosses the face gets
// a fragment. The fragment shader decides, conservatively, whether the
// ray crosses the face's rectangle; nothing here needs the crossing's t.
//
// Bits: a face carries a window of three planes starting at in_bits.x
// (absolute plane number; relative to `first` on output). Faces
// perpendicular to the plane axis at boundary b: window b-1, b, b+1 with
// bits {b-1, b} in halo mode, its PC neighbours' planes (in_bits.y) in
// strict mode. Faces parallel to the plane axis (one plane p): window
// p-1, p, p+1 with bit p; in halo mode also p-1 / p+1 where the crossing's
// coordinate along the plane axis comes within `band` (plus its own error
// bound) of the slab's lower / upper end (see bitplanes.py, "Boundaries").
layout(points) in;
layout(triangle_strip, max_vertices = 4) out;

in ivec4 v_face[];
in ivec2 v_vrange[];
in ivec2 v_bits[];

layout(std430, binding = 0) readonly buffer Edges { double edges[]; };
uniform ivec3 edge_offset;   // where the x, y, z boundaries start in `edges`

uniform dvec3 eye;
uniform dvec3 fwd;
uniform dvec3 right;
uniform dvec3 upv;
uniform int parallel;
uniform double tan_half;     // tan(fov / 2), perspective
uniform double pscale;       // parallel scale
uniform double aspect;       // width / height
uniform double clip_near;    // keep points with dot(p - eye, fwd) >= clip_near
uniform dvec2 ndc_limit;     // viewport plus guard band, NDC half-extents
uniform dvec2 ndc_pad;       // coverage growth, NDC half-extents
uniform dvec3 aff0;
uniform dvec3 affx;
uniform dvec3 affy;
uniform dvec3 err_d;         // perspective: |d32_k - d_k| over all pixels
uniform dvec2 pix_max;       // (width - 1, height - 1)
uniform double abs_tol;      // absolute slack, a tiny fraction of the scene scale
uniform double pos_tol;      // how far the caster's positions may be from these (world units)
uniform int plane_axis;      // the axis planes are numbered along
uniform int first;           // plane number of bit 0
uniform int halo;            // 1: the neighbour planes of slab boundaries too
uniform double band;         // world width of the boundary band (halo)

flat out vec3 g_b;
flat out vec3 g_c;
flat out vec3 g_a;
flat out float g_w;
flat out vec4 g_rect;        // (u0, u1, v0, v1) - eye, grown, rounded outwards
flat out ivec4 g_info;       // (test, base, mask, cond)
flat out vec2 g_thr;         // halo thresholds on p's plane-axis coordinate

vec3 f_a, f_b, f_c;
float f_w;
vec4 f_rect;
ivec4 f_info;
vec2 f_thr;

const double EPS = 1.0 / 16777216.0;    // 2^-24: one float32 rounding of + - *
const double DIV = 1.0 / 1048576.0;     // 2^-20: float32 division, sqrt (GLSL: 2.5, ~4.5 ulp)
const double WIDEN = 1.0 / 4194304.0;   // 2^-22: > one float32 ulp, for outward rounding

double edge(int a, int i) { return edges[edge_offset[a] + i]; }

float down(double x) { return float(x - abs(x) * WIDEN); }
float up(double x) { return float(x + abs(x) * WIDEN); }

void emit(dvec2 p) {
    g_a = f_a;
    g_b = f_b;
    g_c = f_c;
    g_w = f_w;
    g_rect = f_rect;
    g_info = f_info;
    g_thr = f_thr;
    gl_Position = vec4(float(p.x), float(p.y), 0.0, 1.0);
    EmitVertex();
}

double magnitude(dvec3 k) { return abs(k.x) + abs(k.y) * pix_max.x + abs(k.z) * pix_max.y; }

// Face constants for the face at plane c of axis a (rectangle `rect`
// relative to the eye, farthest point at distance thi): the affine forms,
// the grown rectangle, and whether its bounds are valid (segments.geom,
// face_constants, without the t bounds). Returns the crossing point's
// error bounds (ep_u, ep_v).
dvec2 face_constants(int a, int u, int v, double c, dvec4 rect, double thi, out bool valid) {
    double w = c - eye[a];
    double ep_u, ep_v;
    if (parallel != 0) {
        double fa = fwd[a];
        valid = abs(fa) > 1e-100lf;
        double ia = valid ? 1.0 / fa : 0.0;
        dvec3 kt = dvec3((w - aff0[a]) * ia, -affx[a] * ia, -affy[a] * ia);
        dvec3 ku = dvec3(aff0[u], affx[u], affy[u]) + fwd[u] * kt;
        dvec3 kv = dvec3(aff0[v], affx[v], affy[v]) + fwd[v] * kt;
        double abs64 = abs_tol * (1.0 + abs(ia));
        ep_u = 8.0 * EPS * magnitude(ku) + abs64 + abs_tol;
        ep_v = 8.0 * EPS * magnitude(kv) + abs64 + abs_tol;
        f_a = vec3(kt);
        f_b = vec3(ku);
        f_c = vec3(kv);
    } else {
        double sig = abs(w) / thi * (1.0 - WIDEN);
        double q = err_d[a] / sig;
        valid = q <= 0.25;               // false for w == 0 (NaN) too
        q = valid ? q : 0.25;
        double rel_s = (q + 2.0 * EPS + DIV) / (1.0 - q);
        ep_u = 2.0 * thi * (rel_s * (1.0 + err_d[u]) + err_d[u] + EPS * (1.0 + rel_s) * (1.0 + err_d[u])) + abs_tol;
        ep_v = 2.0 * thi * (rel_s * (1.0 + err_d[v]) + err_d[v] + EPS * (1.0 + rel_s) * (1.0 + err_d[v])) + abs_tol;
        f_a = vec3(aff0[a], affx[a], affy[a]);
        f_b = vec3(aff0[u], affx[u], affy[u]);
        f_c = vec3(aff0[v], affx[v], affy[v]);
    }
    f_w = float(w);
    f_rect = vec4(down(rect.x - ep_u), up(rect.y + ep_u), down(rect.z - ep_v), up(rect.w + ep_v));
    return dvec2(ep_u, ep_v);
}

void main() {
    int a = v_face[0].x;
    int u = (a + 1) % 3;
    int v = (a + 2) % 3;
    double c = edge(a, v_face[0].y);
    double u0 = edge(u, v_face[0].z), u1 = edge(u, v_face[0].w);
    double v0 = edge(v, v_vrange[0].x), v1 = edge(v, v_vrange[0].y);
    dvec4 rect = dvec4(u0, u1, v0, v1) - dvec4(eye[u], eye[u], eye[v], eye[v]);
    // Rays parallel to the face never need it (segments.geom; bitplanes.py).
    if (parallel != 0 ? fwd[a] == 0.0 : c == eye[a]) return;

    dvec3 ca = dvec3(right[a], upv[a], fwd[a]);
    dvec3 cu = dvec3(right[u], upv[u], fwd[u]);
    dvec3 cv = dvec3(right[v], upv[v], fwd[v]);
    dvec3 cam[4];
    cam[0] = (c - eye[a]) * ca + rect.x * cu + rect.z * cv;
    cam[1] = (c - eye[a]) * ca + rect.y * cu + rect.z * cv;
    cam[2] = (c - eye[a]) * ca + rect.y * cu + rect.w * cv;
    cam[3] = (c - eye[a]) * ca + rect.x * cu + rect.w * cv;

    dvec2 s[4];
    dvec2 lo = dvec2(1e300lf), hi = dvec2(-1e300lf);
    bool clipped = false;
    for (int k = 0; k < 4; k++) {
        dvec3 p0 = cam[k];
        dvec3 p1 = cam[(k + 1) % 4];
        bool in0 = p0.z >= clip_near;
        clipped = clipped || !in0;
        s[k] = parallel != 0 ? dvec2(p0.x / (pscale * aspect), -p0.y / pscale)
                             : dvec2(p0.x / (p0.z * tan_half * aspect), -p0.y / (p0.z * tan_half));
        if (in0) {
            lo = min(lo, s[k]);
            hi = max(hi, s[k]);
        }
        if (in0 != (p1.z >= clip_near)) {
            double f = (clip_near - p0.z) / (p1.z - p0.z);
            dvec3 m = p0 + f * (p1 - p0);
            m.z = clip_near;
            dvec2 sm = parallel != 0 ? dvec2(m.x / (pscale * aspect), -m.y / pscale)
                                     : dvec2(m.x / (m.z * tan_half * aspect), -m.y / (m.z * tan_half));
            lo = min(lo, sm);
            hi = max(hi, sm);
        }
    }
    // The caster's positions (index space, its ray origins) differ from these by up to
    // pos_tol in world units: coverage reaches that far outside the face; in perspective
    // seen from its nearest point (the clip plane for a clipped face), an offset across
    // the view and along it. Negligible in an ordinary view; with pixels or a field of
    // view a few roundings wide (a parallel scale of 1e-10, 1e-8 degrees, at 1e7 from 0),
    // many pixels of rays the caster starts on or walks along the face.
    dvec2 pad = ndc_pad;
    if (parallel != 0) {
        pad += dvec2(pos_tol / (pscale * aspect), pos_tol / pscale);
    } else {
        double zmin = clipped ? clip_near : min(min(cam[0].z, cam[1].z), min(cam[2].z, cam[3].z));
        pad += dvec2(pos_tol * (1.0 + ndc_limit.x * tan_half * aspect) / (zmin * tan_half * aspect),
                     pos_tol * (1.0 + ndc_limit.y * tan_half) / (zmin * tan_half));
    }
    if (lo.x - pad.x > ndc_limit.x || hi.x + pad.x < -ndc_limit.x ||
        lo.y - pad.y > ndc_limit.y || hi.y + pad.y < -ndc_limit.y) return;   // also: all clipped

    double thi = 0.0;
    if (parallel == 0) {
        double w = c - eye[a];
        double fu = max(abs(rect.x), abs(rect.y));
        double fv = max(abs(rect.z), abs(rect.w));
        thi = sqrt(w * w + fu * fu + fv * fv);
    }
    bool valid;
    dvec2 ep = face_constants(a, u, v, c, rect, thi, valid);

    // The face's bits.
    int base = v_bits[0].x;
    int mask, cond = 0;
    f_thr = vec2(0.0);
    if (a == plane_axis) {
        mask = halo != 0 ? 3 : v_bits[0].y;
    } else {
        mask = 2;
        if (halo != 0) {
            // p's coordinate along the plane axis is p.x when that axis is
            // u, else p.y; the slab of plane p = base + 1 is
            // [edge(pa, p), edge(pa, p + 1)].
            int pa = plane_axis;
            bool along_v = pa == v;
            double e_pa = along_v ? ep.y : ep.x;
            double lo_end = edge(pa, base + 1) - eye[pa];
            double hi_end = edge(pa, base + 2) - eye[pa];
            f_thr = vec2(up(lo_end + band + e_pa), down(hi_end - band - e_pa));
            cond = 3 | (along_v ? 4 : 0);
        }
    }
    f_info = ivec4(valid ? 1 : 0, base - first, mask, cond);

    // Grow the quad (segments.geom).
    double area2 = (s[0].x - s[2].x) * (s[1].y - s[3].y) - (s[1].x - s[3].x) * (s[0].y - s[2].y);
    if (area2 < 0.0) {
        dvec2 tmp = s[1];
        s[1] = s[3];
        s[3] = tmp;
    }
    bool ok = !clipped && lo.x >= -ndc_limit.x && hi.x <= ndc_limit.x && lo.y >= -ndc_limit.y
              && hi.y <= ndc_limit.y && area2 != 0.0;
    dvec2 en[4];
    double eh[4];
    for (int k = 0; k < 4; k++) {
        dvec2 e = s[(k + 1) % 4] - s[k];
        ok = ok && (e.x != 0.0 || e.y != 0.0);
        en[k] = dvec2(e.y, -e.x);
        eh[k] = dot(en[k], s[k]) + pad.x * abs(en[k].x) + pad.y * abs(en[k].y);
    }
    dvec2 outp[4];
    for (int k = 0; k < 4; k++) {
        dvec2 n0 = en[(k + 3) % 4];
        dvec2 n1 = en[k];
        double h0 = eh[(k + 3) % 4];
        double h1 = eh[k];
        double l0 = dot(n0, n0), l1 = dot(n1, n1);
        double len = sqrt(l0 * l1);
        double sn = n0.x * n1.y - n0.y * n1.x;
        double cs = dot(n0, n1);
        ok = ok && !(sn < -1e-12lf * len || cs < -0.999lf * len);
        if (sn < 1e-6lf * len) {
            dvec2 p = s[k];
            outp[k] = p + n0 * (max(h0 - dot(n0, p), 0.0) / l0) + n1 * (max(h1 - dot(n1, p), 0.0) / l1);
        } else {
            outp[k] = dvec2(h0 * n1.y - h1 * n0.y, h1 * n0.x - h0 * n1.x) / sn;
        }
    }
    if (!ok) {
        lo = max(lo - pad, -ndc_limit);
        hi = min(hi + pad, ndc_limit);
        emit(dvec2(lo.x, lo.y));
        emit(dvec2(hi.x, lo.y));
        emit(dvec2(lo.x, hi.y));
        emit(dvec2(hi.x, hi.y));
        EndPrimitive();
        return;
    }
    emit(outp[0]);
    emit(outp[1]);
    emit(outp[3]);
    emit(outp[2]);
    EndPrimitive();
}
