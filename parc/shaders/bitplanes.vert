#version 430
// One plane-proxy face per point: (axis, plane, u0, u1), (v0, v1) indices
// into the supercell boundary table, and (base, strict) for its bits: the
// plane number of bit 0 of the face's three-plane window, and the window
// bits it carries in strict mode. The geometry shader does the work.
in ivec4 in_face;
in ivec2 in_vrange;
in ivec2 in_bits;

out ivec4 v_face;
out ivec2 v_vrange;
out ivec2 v_bits;

void main() {
    v_face = in_face;
    v_vrange = in_vrange;
    v_bits = in_bits;
    gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
}
