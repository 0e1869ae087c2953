#version 430
// Conservative coverage of one axis-aligned proxy face.
//
// Builds the face's corners in float64 from the boundary table, clips the
// quad against the plane "forward distance >= clip_near" (so nothing is
// projected from behind the eye), projects the rest, and emits the
// projected polygon grown to contain its Minkowski sum with the pad
// rectangle (half-extents ndc_pad), so every pixel centre within the pad
// of the face's outline is covered whatever the rasterization rules and
// vertex snapping do. The fragment shader then decides exactly, per
// pixel, whether the pixel's ray crosses the face.
//
// Faces reaching past the guard band around the viewport, and polygons
// too thin to orient reliably (faces seen edge-on), emit instead their
// bounding box grown by the pad and cut to the guard band: simpler, always
// safe, and it keeps emitted coordinates small enough for float32.
// Everything up to the emitted corners is float64, so a face next to the
// eye (projecting far larger than the screen) loses no precision.
layout(points) in;
layout(triangle_strip, max_vertices = 5) out;

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

flat out int g_axis;
flat out double g_plane;
flat out dvec4 g_rect;       // (u0, u1, v0, v1), world

int f_axis;
double f_plane;
dvec4 f_rect;

double edge(int a, int i) { return edges[edge_offset[a] + i]; }

void emit(dvec2 p) {
    g_axis = f_axis;
    g_plane = f_plane;
    g_rect = f_rect;
    gl_Position = vec4(float(p.x), float(p.y), 0.0, 1.0);
    EmitVertex();
}

void main() {
    int a = v_face[0].x;
    int u = (a + 1) % 3;
    int v = (a + 2) % 3;
    double c = edge(a, v_face[0].y);
    double u0 = edge(u, v_face[0].z), u1 = edge(u, v_face[0].w);
    double v0 = edge(v, v_vrange[0].x), v1 = edge(v, v_vrange[0].y);
    f_axis = a;
    f_plane = c;
    f_rect = dvec4(u0, u1, v0, v1);

    // Corners in camera coordinates (right, up, forward), relative to the eye.
    dvec3 cam[4];
    for (int k = 0; k < 4; k++) {
        dvec3 p;
        p[a] = c;
        p[u] = (k == 1 || k == 2) ? u1 : u0;
        p[v] = (k >= 2) ? v1 : v0;
        dvec3 q = p - eye;
        cam[k] = dvec3(dot(q, right), dot(q, upv), dot(q, fwd));
    }

    // Sutherland-Hodgman against forward >= clip_near: at most 5 corners.
    dvec3 poly[5];
    int n = 0;
    for (int k = 0; k < 4; k++) {
        dvec3 p0 = cam[k];
        dvec3 p1 = cam[(k + 1) % 4];
        bool in0 = p0.z >= clip_near;
        bool in1 = p1.z >= clip_near;
        if (in0) poly[n++] = p0;
        if (in0 != in1) {
            double s = (clip_near - p0.z) / (p1.z - p0.z);
            dvec3 m = p0 + s * (p1 - p0);
            m.z = clip_near;
            poly[n++] = m;
        }
    }
    if (n == 0) return;

    // Project (our NDC y points down the image rows, so GL window row r is
    // image row r and read-back needs no flip).
    dvec2 s[5];
    dvec2 lo = dvec2(1e300), hi = dvec2(-1e300);
    for (int k = 0; k < n; k++) {
        if (parallel != 0) {
            s[k] = dvec2(poly[k].x / (pscale * aspect), -poly[k].y / pscale);
        } else {
            s[k] = dvec2(poly[k].x / (poly[k].z * tan_half * aspect), -poly[k].y / (poly[k].z * tan_half));
        }
        lo = min(lo, s[k]);
        hi = max(hi, s[k]);
    }
    if (lo.x - ndc_pad.x > ndc_limit.x || hi.x + ndc_pad.x < -ndc_limit.x ||
        lo.y - ndc_pad.y > ndc_limit.y || hi.y + ndc_pad.y < -ndc_limit.y) return;

    double area2 = 0.0;   // twice the signed area: > 0 counter-clockwise
    for (int k = 0; k < n; k++) {
        dvec2 p = s[k], q = s[(k + 1) % n];
        area2 += p.x * q.y - p.y * q.x;
    }

    // Grow the polygon: move every edge's line out by the pad rectangle's
    // support in its normal direction, rx |n.x| + ry |n.y|, and join the
    // moved lines at their intersections (mitres). The result contains
    // the Minkowski sum of the polygon and the pad rectangle, with the
    // same number of corners (2 or 3 triangles). Polygons that reach past
    // the guard band, are degenerate or not convex after rounding, or have
    // a corner so sharp that its mitre would spike, take the bounding box.
    if (area2 < 0.0) {
        // Clockwise on screen (a back face, with our flipped y): reverse.
        for (int k = 0; k < n / 2; k++) {
            dvec2 tmp = s[k];
            s[k] = s[n - 1 - k];
            s[n - 1 - k] = tmp;
        }
    }
    bool ok = lo.x >= -ndc_limit.x && hi.x <= ndc_limit.x && lo.y >= -ndc_limit.y && hi.y <= ndc_limit.y
              && area2 != 0.0;
    // Edges with unit outward normals (repeated corners dropped).
    dvec2 en[5];
    double eh[5];
    dvec2 ev[5];
    int m = 0;
    if (ok) {
        for (int k = 0; k < n; k++) {
            dvec2 e = s[(k + 1) % n] - s[k];
            double len = length(e);
            if (len == 0.0) continue;
            dvec2 nk = dvec2(e.y, -e.x) / len;
            en[m] = nk;
            eh[m] = dot(nk, s[k]) + ndc_pad.x * abs(nk.x) + ndc_pad.y * abs(nk.y);
            ev[m] = s[k];
            m++;
        }
        ok = m >= 3;
    }
    dvec2 outp[5];
    for (int k = 0; k < m && ok; k++) {
        // Corner between edge k-1 and edge k, at ev[k].
        dvec2 n0 = en[(k + m - 1) % m];
        dvec2 n1 = en[k];
        double h0 = eh[(k + m - 1) % m];
        double h1 = eh[k];
        double sn = n0.x * n1.y - n0.y * n1.x;     // sin of the turn (> 0: convex)
        double cs = dot(n0, n1);                   // cos of the turn
        if (sn < -1e-12 || cs < -0.999) {
            ok = false;                            // reflex, or a spike sharper than ~2.6 degrees
        } else if (sn < 1e-6) {
            // Nearly straight on: the two moved lines almost coincide; a
            // point beyond both (n . p >= h for each) stands in for the mitre.
            dvec2 v = ev[k];
            outp[k] = v + n0 * max(h0 - dot(n0, v), 0.0) + n1 * max(h1 - dot(n1, v), 0.0);
        } else {
            outp[k] = dvec2(h0 * n1.y - h1 * n0.y, h1 * n0.x - h0 * n1.x) / sn;
        }
    }
    if (!ok) {
        lo = max(lo - ndc_pad, -ndc_limit);
        hi = min(hi + ndc_pad, ndc_limit);
        emit(dvec2(lo.x, lo.y));
        emit(dvec2(hi.x, lo.y));
        emit(dvec2(lo.x, hi.y));
        emit(dvec2(hi.x, hi.y));
        EndPrimitive();
        return;
    }
    // Triangle strip over a convex polygon: 0, 1, m-1, 2, m-2, ...
    int i = 1, j = m - 1;
    emit(outp[0]);
    while (i <= j) {
        emit(outp[i++]);
        if (i <= j) emit(outp[j--]);
    }
    EndPrimitive();
}
