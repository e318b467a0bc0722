#version 330 core
// Coloured points and lines of the 3-D view: world positions through one view-projection matrix.

uniform mat4 u_view_projection;
uniform float u_point_size;

layout(location = 0) in vec3 a_position;
layout(location = 1) in vec4 a_colour;

out vec4 v_colour;

void main() {
  v_colour = a_colour;
  gl_Position = u_view_projection * vec4(a_position, 1.0);
  gl_PointSize = u_point_size;
}
