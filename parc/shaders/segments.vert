#version 430
// One proxy face per point: (axis, plane, u0, u1) and (v0, v1), indices
// into the supercell boundary table. The geometry shader does the work.
in ivec4 in_face;
in ivec2 in_vrange;

out ivec4 v_face;
out ivec2 v_vrange;

void main() {
    v_face = in_face;
    v_vrange = in_vrange;
    gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
}
