#version 330 core
// A textured quad without vertex buffers: four vertices of a triangle strip from gl_VertexID.
// u_rect is the quad in target pixels with the origin at the top-left corner (x0, y0, x1, y1);
// the image's first row (texture t = 0) lands at the top.

uniform vec4 u_rect;
uniform vec2 u_target_size;

out vec2 v_texcoord;

void main() {
  vec2 corner = vec2(gl_VertexID & 1, (gl_VertexID >> 1) & 1);  // (0,0) (1,0) (0,1) (1,1)
  vec2 pixel = mix(u_rect.xy, u_rect.zw, corner);
  vec2 ndc = vec2(pixel.x / u_target_size.x * 2.0 - 1.0, 1.0 - pixel.y / u_target_size.y * 2.0);
  v_texcoord = corner;
  gl_Position = vec4(ndc, 0.0, 1.0);
}
