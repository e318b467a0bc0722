#version 330 core
// A grey NIR frame from an R8 or R16 texture, normalised by the frame's bit depth (a 10-bit frame
// in a 16-bit container reaches full white at code 1023, not 65535). Optionally marks clipped
// pixels: codes at the top of the range (saturated) in one colour, code 0 (black) in another.

uniform sampler2D u_image;
uniform float u_container_max;   // 255 for R8, 65535 for R16
uniform float u_max_code;        // 2^bit_depth - 1
uniform bool u_highlight_clipping;
uniform vec3 u_saturated_colour;
uniform vec3 u_black_colour;

in vec2 v_texcoord;
out vec4 out_colour;

void main() {
  float code = floor(texture(u_image, v_texcoord).r * u_container_max + 0.5);
  vec3 colour = vec3(clamp(code / u_max_code, 0.0, 1.0));
  if (u_highlight_clipping) {
    if (code >= u_max_code) {
      colour = u_saturated_colour;
    } else if (code <= 0.0) {
      colour = u_black_colour;
    }
  }
  out_colour = vec4(colour, 1.0);
}
