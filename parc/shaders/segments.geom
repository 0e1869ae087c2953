#version 430
// Conservative coverage of one axis-aligned proxy face, and the face's
// constants for the fragment shader.
//
// Builds the face's corners in float64 from the boundary table, clips the
// quad against the plane "forward distance >= clip_near" (so nothing is
// projected from behind the eye), projects the rest, and emits the
// projected polygon grown to contain its Minkowski sum with the pad
// rectangle (half-extents ndc_pad), so every pixel centre within the pad
// of the face's outline is covered whatever the rasterization rules and
// vertex snapping do. The fragment shader then decides, per pixel and
// conservatively, whether the pixel's ray crosses the face and where.
//
// Faces reaching past the guard band around the viewport, and polygons
// too thin to orient reliably (faces seen edge-on), emit instead their
// bounding box grown by the pad and cut to the guard band: simpler, always
// safe, and it keeps emitted coordinates small enough for float32.
// Everything here is float64, so a face next to the eye (projecting far
// larger than the screen) loses no precision; this stage costs little
// next to triangle setup and fragments on llvmpipe.
//
// Face constants (see raster.py, "Error bounds"): over pixel indices
// (x, y), the fragment shader evaluates three affine forms k0 + kx x + ky y
// in float32 -- perspective: the ray direction's components along the
// face's axis a and spanning axes u, v; parallel: the crossing's t and its
// in-plane coordinates (a parallel view maps pixels affinely onto any
// plane). Here, in float64, each face gets bounds that hold for every ray
// that really crosses it: err (e_abs, e_rel) with |t32 - t| <= e_abs +
// e_rel |t32|, and the rectangle grown by the crossing point's error
// bound and rounded outwards. A face whose bounds are not tighter than its
// own range of t (seen nearly edge-on) writes that range instead; one
// whose bounds do not hold at all (its plane through the eye, or within
// the direction's error of it) writes the range and discards nothing.
layout(points) in;
layout(triangle_strip, max_vertices = 4) out;

in ivec4 v_face[];
in ivec2 v_vrange[];

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
// Pixel (x, y) -> perspective: ray direction; parallel: origin - eye, as
// aff0 + affx x + affy y (float64, the caster's formula rearranged).
uniform dvec3 aff0;
uniform dvec3 affx;
uniform dvec3 affy;
uniform dvec3 err_d;         // perspective: |d32_k - d_k| over all pixels
uniform dvec2 pix_max;       // (width - 1, height - 1)
uniform double abs_tol;      // absolute slack, a tiny fraction of the scene scale
uniform double pos_tol;      // how far the caster's positions may be from these (world units)
uniform int face_range;      // 1: every face writes its own range of t (light buffers)

flat out vec3 g_a;           // perspective: d_a, d_u, d_v; parallel: t, p_u, p_v
flat out vec3 g_b;
flat out vec3 g_c;
flat out float g_w;          // perspective: plane - eye_a
flat out vec4 g_rect;        // (u0, u1, v0, v1) - eye, grown, rounded outwards
flat out vec2 g_err;         // (e_abs, e_rel), or (-1 or -2, _): write the t range
flat out vec2 g_trange;      // t on the face lies in [x, y]

vec3 f_a, f_b, f_c;
float f_w;
vec4 f_rect;
vec2 f_err;
vec2 f_trange;

const double EPS = 1.0 / 16777216.0;    // 2^-24: one float32 rounding of + - *
const double DIV = 1.0 / 1048576.0;     // 2^-20: float32 division, sqrt (GLSL: 2.5, ~4.5 ulp)
const double WIDEN = 1.0 / 4194304.0;   // 2^-22: > one float32 ulp, for outward rounding

double edge(int a, int i) { return edges[edge_offset[a] + i]; }

// Rounded to float32 below / above x (by more than any rounding mode's error).
float down(double x) { return float(x - abs(x) * WIDEN); }
float up(double x) { return float(x + abs(x) * WIDEN); }

void emit(dvec2 p) {
    g_a = f_a;
    g_b = f_b;
    g_c = f_c;
    g_w = f_w;
    g_rect = f_rect;
    g_err = f_err;
    g_trange = f_trange;
    gl_Position = vec4(float(p.x), float(p.y), 0.0, 1.0);
    EmitVertex();
}

// Largest |k0 + kx x + ky y| term sum over the image's pixels.
double magnitude(dvec3 k) { return abs(k.x) + abs(k.y) * pix_max.x + abs(k.z) * pix_max.y; }

// The face constants (f_*), for the face at plane c of axis a with
// rectangle `rect` relative to the eye and t range [tlo, thi].
void face_constants(int a, int u, int v, double c, dvec4 rect, double tlo, double thi) {
    double w = c - eye[a];
    double ep_u, ep_v;                   // bounds on the crossing point's error
    double e_abs, e_rel;
    bool valid;                          // the bounds hold (else: no face test)
    if (parallel != 0) {
        // t = (w - o_a) / f_a and p = o + t f (relative to the eye): affine
        // in (x, y); evaluating k0 + kx x + ky y in float32 (rounded
        // coefficients, two roundings) is off by <= 3 * 2^-24 * magnitude;
        // 8 * 2^-24 doubles it. abs64 covers the float64 coefficients and
        // the caster's own rounding of o (2^-52 of the coordinates).
        double fa = fwd[a];
        valid = abs(fa) > 1e-100lf;
        double ia = valid ? 1.0 / fa : 0.0;
        dvec3 kt = dvec3((w - aff0[a]) * ia, -affx[a] * ia, -affy[a] * ia);
        dvec3 ku = dvec3(aff0[u], affx[u], affy[u]) + fwd[u] * kt;
        dvec3 kv = dvec3(aff0[v], affx[v], affy[v]) + fwd[v] * kt;
        double abs64 = abs_tol * (1.0 + abs(ia));
        e_abs = 8.0 * EPS * magnitude(kt) + abs64 + abs_tol;
        e_rel = 4.0 * EPS;               // rounding of t -+ e
        ep_u = 8.0 * EPS * magnitude(ku) + abs64 + abs_tol;
        ep_v = 8.0 * EPS * magnitude(kv) + abs64 + abs_tol;
        f_a = vec3(kt);
        f_b = vec3(ku);
        f_c = vec3(kv);
    } else {
        // A ray that crosses the face at t has |d_a| / |d| = |w| / t >=
        // |w| / thi =: sig, and |d| >= 1, so the float32 d_a is off by at
        // most q = err_d[a] / sig relative. Then r = w / d_a is off by
        // rel_s, the crossing point r (d_u, d_v) by ep (using |r| <= t <=
        // thi), and t = r |d| by rel_t; all doubled.
        double sig = abs(w) / thi * (1.0 - WIDEN);
        double q = err_d[a] / sig;
        valid = q <= 0.25;               // false for w == 0 (NaN) too
        q = valid ? q : 0.25;
        double rel_s = (q + 2.0 * EPS + DIV) / (1.0 - q);
        double nu = length(err_d) + DIV * (1.0 + length(err_d));
        double rel_t = (1.0 + rel_s) * (1.0 + nu) * (1.0 + EPS) - 1.0;
        // |d|'s own rounding can pass |d| (a field of view within ~1e-4 degree of 180: the
        // direction's components across the image reach 1e6, and the bound on their float32
        // roundings passes 1); then t -+ e bounds nothing, and past rel_t = 1 e_rel turns
        // negative.
        valid = valid && rel_t <= 0.25;
        e_abs = abs_tol;
        e_rel = 2.0 * rel_t / (1.0 - rel_t) + 4.0 * EPS;
        ep_u = 2.0 * thi * (rel_s * (1.0 + err_d[u]) + err_d[u] + EPS * (1.0 + rel_s) * (1.0 + err_d[u]))
               + abs_tol;
        ep_v = 2.0 * thi * (rel_s * (1.0 + err_d[v]) + err_d[v] + EPS * (1.0 + rel_s) * (1.0 + err_d[v]))
               + abs_tol;
        f_a = vec3(aff0[a], affx[a], affy[a]);
        f_b = vec3(aff0[u], affx[u], affy[u]);
        f_c = vec3(aff0[v], affx[v], affy[v]);
    }
    // The face's own range is tighter than t -+ e (seen nearly edge-on,
    // or face-on in a parallel view): write the range.
    bool range = !valid || e_abs + e_rel * max(abs(tlo), abs(thi)) >= thi - tlo;
    f_w = float(w);
    f_rect = vec4(down(rect.x - ep_u), up(rect.y + ep_u), down(rect.z - ep_v), up(rect.w + ep_v));
    // g_err.x: -2 range without face test, -1 range with it, else e_abs.
    f_err = vec2(!valid || face_range != 0 ? -2.0 : (range ? -1.0 : up(e_abs)), up(e_rel));
    // The face's range of t, widened by 2^-21 relative (float32 rounding is
    // 2^-24; the caster's normalization and float64 arithmetic far less)
    // plus abs_tol.
    f_trange = vec2(down(tlo - abs(tlo) * 8.0 * WIDEN - abs_tol), up(thi + abs(thi) * 8.0 * WIDEN + abs_tol));
}

void main() {
    int a = v_face[0].x;
    int u = (a + 1) % 3;
    int v = (a + 2) % 3;
    double c = edge(a, v_face[0].y);
    double u0 = edge(u, v_face[0].z), u1 = edge(u, v_face[0].w);
    double v0 = edge(v, v_vrange[0].x), v1 = edge(v, v_vrange[0].y);
    dvec4 rect = dvec4(u0, u1, v0, v1) - dvec4(eye[u], eye[u], eye[v], eye[v]);
    // A ray exactly parallel to the face never needs it: where such a ray
    // enters or leaves the PC region it crosses another outer face whose
    // axis it is not parallel to (a face perpendicular to the entering
    // axis, or the side face where a PC neighbour meets an empty diagonal
    // one). In a parallel view with f_a = 0 every ray is parallel to the
    // face; in perspective with the eye in the face's plane every ray
    // meeting the face either lies in the plane or meets it at the eye
    // (t = 0, covered by the eye-inside rule).
    if (parallel != 0 ? fwd[a] == 0.0 : c == eye[a]) return;

    // Corners in camera coordinates (right, up, forward), relative to the
    // eye, counter-clockwise in (u, v). Loops below have constant trip
    // counts and indices: llvmpipe runs a geometry shader as SIMD over
    // primitives, where per-lane array indices are costly.
    dvec3 ca = dvec3(right[a], upv[a], fwd[a]);
    dvec3 cu = dvec3(right[u], upv[u], fwd[u]);
    dvec3 cv = dvec3(right[v], upv[v], fwd[v]);
    dvec3 cam[4];
    cam[0] = (c - eye[a]) * ca + rect.x * cu + rect.z * cv;
    cam[1] = (c - eye[a]) * ca + rect.y * cu + rect.z * cv;
    cam[2] = (c - eye[a]) * ca + rect.y * cu + rect.w * cv;
    cam[3] = (c - eye[a]) * ca + rect.x * cu + rect.w * cv;

    // Project (our NDC y points down the image rows, so GL window row r is
    // image row r and read-back needs no flip). A face reaching behind
    // forward = clip_near is cut there (nothing is projected from behind
    // the eye) and takes the bounding box of what is left.
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
            // Where the edge k, k+1 crosses the clip plane.
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

    // The range of t over the face: forward distance (parallel) or
    // distance from the eye (perspective; the nearest point is the eye
    // clamped to the rectangle, the farthest a corner).
    double tlo, thi;
    if (parallel != 0) {
        tlo = min(min(cam[0].z, cam[1].z), min(cam[2].z, cam[3].z));
        thi = max(max(cam[0].z, cam[1].z), max(cam[2].z, cam[3].z));
    } else {
        double w = c - eye[a];
        double gu = max(max(rect.x, 0.0), -rect.y);     // eye's distance to [u0, u1]
        double gv = max(max(rect.z, 0.0), -rect.w);
        double fu = max(abs(rect.x), abs(rect.y));      // to the farther end
        double fv = max(abs(rect.z), abs(rect.w));
        tlo = sqrt(w * w + gu * gu + gv * gv);
        thi = sqrt(w * w + fu * fu + fv * fv);
    }
    face_constants(a, u, v, c, rect, tlo, thi);

    // Grow the quad: move every edge's line out by the pad rectangle's
    // support in its normal direction, rx |n.x| + ry |n.y|, and join the
    // moved lines at their intersections (mitres). The result contains
    // the Minkowski sum of the quad and the pad rectangle (2 triangles).
    // Normals are not normalized: the support, the moved line and the
    // mitre are all homogeneous in n. Quads that were clipped, reach past
    // the guard band, are degenerate or not convex after rounding, or have
    // a corner so sharp that its mitre would spike, take the bounding box.
    double area2 = (s[0].x - s[2].x) * (s[1].y - s[3].y) - (s[1].x - s[3].x) * (s[0].y - s[2].y);
    if (area2 < 0.0) {
        // Clockwise on screen (a back face, with our flipped y): reverse.
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
        // Corner between edge k-1 and edge k, at s[k].
        dvec2 n0 = en[(k + 3) % 4];
        dvec2 n1 = en[k];
        double h0 = eh[(k + 3) % 4];
        double h1 = eh[k];
        double l0 = dot(n0, n0), l1 = dot(n1, n1);
        double len = sqrt(l0 * l1);
        double sn = n0.x * n1.y - n0.y * n1.x;     // |n0| |n1| sin of the turn (> 0: convex)
        double cs = dot(n0, n1);                   // |n0| |n1| cos of the turn
        // Reflex, or a spike sharper than ~2.6 degrees: the bounding box.
        ok = ok && !(sn < -1e-12lf * len || cs < -0.999lf * len);
        if (sn < 1e-6lf * len) {
            // Nearly straight on: the two moved lines almost coincide; a
            // point beyond both (n . p >= h for each) stands in for the mitre.
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
    // Triangle strip over the convex quad: 0, 1, 3, 2.
    emit(outp[0]);
    emit(outp[1]);
    emit(outp[3]);
    emit(outp[2]);
    EndPrimitive();
}
