#version 330 core
// Round points (when u_round_points is set) so a dense cloud reads as surfaces, not as squares.

uniform bool u_round_points;

in vec4 v_colour;
out vec4 o_colour;

void main() {
  if (u_round_points) {
    vec2 offset = gl_PointCoord - vec2(0.5);
    if (dot(offset, offset) > 0.25) discard;
  }
  o_colour = v_colour;
}
