#include "ui/panels/feed_panel.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <opencv2/core.hpp>

#include "ui/colour_maps.hpp"
#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

constexpr float kMinZoom = 0.1f;   // relative to fit
constexpr float kMaxZoom = 200.0f;
constexpr float kWheelStep = 1.25f;

void set_colour_uniform(GLint location, ImU32 colour) {
  const ImVec4 c = to_vec4(colour);
  glUniform3f(location, c.x, c.y, c.z);
}

std::uint32_t pixel_code(const cv::Mat& image, int x, int y) {
  return image.type() == CV_16UC1 ? image.at<std::uint16_t>(y, x) : image.at<std::uint8_t>(y, x);
}

std::string depth_text(const Frame& frame) {
  if (frame.image.type() == CV_16UC1 && frame.bit_depth < 16)
    return fmt::format("{}-bit in 16-bit words", frame.bit_depth);
  return fmt::format("{}-bit", frame.bit_depth);
}

}  // namespace

FeedPanel::FeedPanel(const std::filesystem::path& shader_dir)
    : program_(gl::load_program(shader_dir, "image_quad")) {
  u_rect_ = program_.uniform("u_rect");
  u_target_size_ = program_.uniform("u_target_size");
  u_image_ = program_.uniform("u_image");
  u_container_max_ = program_.uniform("u_container_max");
  u_max_code_ = program_.uniform("u_max_code");
  u_highlight_ = program_.uniform("u_highlight_clipping");
  u_saturated_colour_ = program_.uniform("u_saturated_colour");
  u_black_colour_ = program_.uniform("u_black_colour");
  // Core profile draws need a vertex array object even when the vertices come from gl_VertexID.
  glGenVertexArrays(1, &vertex_array_);
}

FeedPanel::~FeedPanel() {
  if (vertex_array_ != 0) glDeleteVertexArrays(1, &vertex_array_);
}

void FeedPanel::fit() {
  zoom_ = 1.0f;
  pan_ = ImVec2(0.0f, 0.0f);
}

void FeedPanel::set_view(float zoom, ImVec2 pan) {
  zoom_ = std::clamp(zoom, kMinZoom, kMaxZoom);
  pan_ = pan;
}

void FeedPanel::draw(const Snapshot& snapshot) {
  const Frame* frame = snapshot.frame && !snapshot.frame->image.empty() ? &*snapshot.frame : nullptr;
  const bool has_corrected = frame != nullptr && !snapshot.corrected_image.empty() &&
                             snapshot.corrected_image.size() == frame->image.size();
  draw_tool_row(frame, has_corrected);
  Frame corrected;
  showing_corrected_ = show_corrected && has_corrected;
  if (showing_corrected_) {
    if (corrected_source_.data != snapshot.corrected_image.data) {
      cv::Mat grey;
      snapshot.corrected_image.convertTo(grey, CV_8U);  // G(I)/V is on the 0..255 scale already
      corrected_grey_ = grey;
      corrected_source_ = snapshot.corrected_image;
    }
    corrected = *frame;
    corrected.image = corrected_grey_;
    corrected.bit_depth = 8;
    frame = &corrected;
  }

  const ImVec2 avail = ImGui::GetContentRegionAvail();
  view_.min = ImGui::GetCursorScreenPos();
  view_.max = ImVec2(view_.min.x + std::floor(avail.x), view_.min.y + std::floor(avail.y));
  image_ = {};
  scale_ = 0.0f;
  if (view_.width() < 16.0f || view_.height() < 16.0f) return;

  ImGui::InvisibleButton("##feed_view", view_.size());
  const bool hovered = ImGui::IsItemHovered();
  const bool active = ImGui::IsItemActive();
  ImDrawList* draw = ImGui::GetWindowDrawList();

  if (frame == nullptr) {
    draw->AddRectFilled(view_.min, view_.max, colours::feed_bg);
    const char* line1 = "No frame yet";
    const char* line2 = snapshot.state == WorkerState::Failed ? snapshot.message.c_str()
                                                              : "Press Start (Space) or Step (S) to process frames";
    const ImVec2 s1 = ImGui::CalcTextSize(line1);
    const ImVec2 s2 = ImGui::CalcTextSize(line2);
    const ImVec2 c = view_.centre();
    draw->AddText(ImVec2(c.x - 0.5f * s1.x, c.y - s1.y - 2.0f), colours::text, line1);
    draw->AddText(ImVec2(c.x - 0.5f * s2.x, c.y + 2.0f), colours::text_dim, line2);
    return;
  }

  handle_input(*frame, hovered, active);
  update_geometry(*frame);
  render(*frame);
  draw->AddImage(gl::texture_id(target_.texture()), view_.min, view_.max, ImVec2(0.0f, 1.0f), ImVec2(1.0f, 0.0f));
  draw->PushClipRect(view_.min, view_.max, true);
  draw->AddRect(ImVec2(image_.min.x - 1.0f, image_.min.y - 1.0f), ImVec2(image_.max.x + 1.0f, image_.max.y + 1.0f),
                colours::border);
  points_drawn_ = 0;
  if (show_points && snapshot.trajectory) draw_tracked_points(*snapshot.trajectory);
  draw_overlays(snapshot, *frame, hovered);
  draw->PopClipRect();
}

void FeedPanel::draw_tool_row(const Frame* frame, bool has_corrected) {
  ImGui::Checkbox("Clipping", &highlight_clipping);
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip("Mark pixels at the top code of the bit depth (saturated) in red\n"
                      "and pixels at code 0 (black) in blue");
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const float swatch = std::round(ImGui::GetTextLineHeight() * 0.75f);
  const auto legend = [&](const char* text, ImU32 colour) {
    ImGui::SameLine(0.0f, 14.0f);
    const ImVec2 p = ImGui::GetCursorScreenPos();
    const float y = p.y + 0.5f * (ImGui::GetFrameHeight() - swatch);
    draw->AddRectFilled(ImVec2(p.x, y), ImVec2(p.x + swatch, y + swatch), colour, 2.0f);
    ImGui::Dummy(ImVec2(swatch, ImGui::GetFrameHeight()));
    ImGui::SameLine(0.0f, 5.0f);
    ImGui::AlignTextToFramePadding();
    ImGui::TextColored(to_vec4(highlight_clipping ? colours::text : colours::text_dim), "%s", text);
  };
  legend("saturated", colours::saturated);
  legend("black", colours::black);
  ImGui::SameLine(0.0f, 24.0f);
  ImGui::Checkbox("Info", &show_info);
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("Show the frame and processing overlays on the image");
  ImGui::SameLine(0.0f, 16.0f);
  ImGui::Checkbox("Points", &show_points);
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("The odometry's active points in this frame, coloured by depth (red near, blue far)");
  ImGui::SameLine(0.0f, 16.0f);
  if (!has_corrected) ImGui::BeginDisabled();
  ImGui::Checkbox("Corrected", &show_corrected);
  if (!has_corrected) ImGui::EndDisabled();
  if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
    ImGui::SetTooltip(has_corrected ? "Show G(I)/V, the photometrically corrected frame the odometry sees"
                                    : "No corrected frame: the pipeline mode has no photometric calibration");

  // Right-aligned: zoom readout and view buttons.
  const std::string zoom_text = scale_ > 0.0f ? fmt::format("Zoom {:.0f} %", 100.0f * scale_) : std::string("Zoom –");
  const ImGuiStyle& style = ImGui::GetStyle();
  const float button_fit = ImGui::CalcTextSize("Fit").x + 2.0f * style.FramePadding.x;
  const float button_one = ImGui::CalcTextSize("1:1").x + 2.0f * style.FramePadding.x;
  const float zoom_width = ImGui::CalcTextSize("Zoom 10000 %").x;
  const float right_width = zoom_width + button_fit + button_one + 2.0f * style.ItemSpacing.x;
  const float x = ImGui::GetWindowContentRegionMax().x - right_width;
  const float left_end = ImGui::GetItemRectMax().x - ImGui::GetWindowPos().x;
  // On the same row when it fits, else right-aligned on a row of its own.
  if (x >= left_end + 20.0f)
    ImGui::SameLine(x);
  else
    ImGui::SetCursorPosX(std::max(x, ImGui::GetCursorPosX()));
  ImGui::AlignTextToFramePadding();
  right_aligned_text(zoom_width, zoom_text.c_str(), colours::text_dim);
  ImGui::SameLine();
  const bool has_frame = frame != nullptr;
  if (!has_frame) ImGui::BeginDisabled();
  if (ImGui::Button("Fit")) fit();
  if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
    ImGui::SetTooltip("Fit the whole frame to the panel (double-click the image)");
  ImGui::SameLine();
  if (ImGui::Button("1:1") && has_frame && scale_ > 0.0f) {
    const float factor = 1.0f / scale_;
    set_view(zoom_ * factor, ImVec2(pan_.x * factor, pan_.y * factor));
  }
  if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
    ImGui::SetTooltip("One image pixel per screen pixel");
  if (!has_frame) ImGui::EndDisabled();
}

void FeedPanel::handle_input(const Frame& frame, bool hovered, bool active) {
  const ImGuiIO& io = ImGui::GetIO();
  if (hovered && ImGui::IsMouseDoubleClicked(ImGuiMouseButton_Left)) {
    fit();
    return;
  }
  if (active && ImGui::IsMouseDragging(ImGuiMouseButton_Left, 0.0f)) {
    pan_.x += io.MouseDelta.x;
    pan_.y += io.MouseDelta.y;
  }
  if (hovered && io.MouseWheel != 0.0f) {
    const float new_zoom = std::clamp(zoom_ * std::pow(kWheelStep, io.MouseWheel), kMinZoom, kMaxZoom);
    const float factor = new_zoom / zoom_;
    // Keep the image point under the cursor where it is.
    const ImVec2 c = view_.centre();
    const ImVec2 d(io.MousePos.x - c.x, io.MousePos.y - c.y);
    pan_ = ImVec2(d.x - (d.x - pan_.x) * factor, d.y - (d.y - pan_.y) * factor);
    zoom_ = new_zoom;
  }
  // Keep at least a strip of the image in view.
  const float fit_scale = std::min(view_.width() / static_cast<float>(frame.width()),
                                   view_.height() / static_cast<float>(frame.height()));
  const float half_w = 0.5f * (static_cast<float>(frame.width()) * fit_scale * zoom_ + view_.width()) - 32.0f;
  const float half_h = 0.5f * (static_cast<float>(frame.height()) * fit_scale * zoom_ + view_.height()) - 32.0f;
  pan_.x = std::clamp(pan_.x, -std::max(half_w, 0.0f), std::max(half_w, 0.0f));
  pan_.y = std::clamp(pan_.y, -std::max(half_h, 0.0f), std::max(half_h, 0.0f));
}

void FeedPanel::update_geometry(const Frame& frame) {
  const float fit_scale = std::min(view_.width() / static_cast<float>(frame.width()),
                                   view_.height() / static_cast<float>(frame.height()));
  scale_ = fit_scale * zoom_;
  const float w = static_cast<float>(frame.width()) * scale_;
  const float h = static_cast<float>(frame.height()) * scale_;
  const ImVec2 c = view_.centre();
  image_.min = ImVec2(std::round(c.x + pan_.x - 0.5f * w), std::round(c.y + pan_.y - 0.5f * h));
  image_.max = ImVec2(image_.min.x + std::round(w), image_.min.y + std::round(h));
}

void FeedPanel::render(const Frame& frame) {
  if (uploaded_.data != frame.image.data || uploaded_.size != frame.image.size ||
      uploaded_.type() != frame.image.type()) {
    texture_.upload(frame.image);
    uploaded_ = frame.image;
  }
  const ImVec2 fb_scale = ImGui::GetIO().DisplayFramebufferScale;
  const int target_w = std::max(1, static_cast<int>(std::lround(view_.width() * fb_scale.x)));
  const int target_h = std::max(1, static_cast<int>(std::lround(view_.height() * fb_scale.y)));
  const RenderKey key{uploaded_.data,
                      {image_.min.x - view_.min.x, image_.min.y - view_.min.y, image_.max.x - view_.min.x,
                       image_.max.y - view_.min.y},
                      target_w,
                      target_h,
                      highlight_clipping,
                      frame.max_value()};
  if (key == rendered_) return;
  rendered_ = key;
  target_.resize(target_w, target_h);

  gl::FramebufferBindingGuard guard;
  target_.bind();
  const ImVec4 bg = to_vec4(colours::feed_bg);
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_BLEND);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  glClearColor(bg.x, bg.y, bg.z, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);

  program_.use();
  glUniform4f(u_rect_, (image_.min.x - view_.min.x) * fb_scale.x, (image_.min.y - view_.min.y) * fb_scale.y,
              (image_.max.x - view_.min.x) * fb_scale.x, (image_.max.y - view_.min.y) * fb_scale.y);
  glUniform2f(u_target_size_, static_cast<float>(target_w), static_cast<float>(target_h));
  glUniform1i(u_image_, 0);
  glUniform1f(u_container_max_, texture_.container_max());
  glUniform1f(u_max_code_, static_cast<float>(frame.max_value()));
  glUniform1i(u_highlight_, highlight_clipping ? 1 : 0);
  set_colour_uniform(u_saturated_colour_, colours::saturated);
  set_colour_uniform(u_black_colour_, colours::black);

  GLint previous_texture = 0;
  glActiveTexture(GL_TEXTURE0);
  glGetIntegerv(GL_TEXTURE_BINDING_2D, &previous_texture);
  glBindTexture(GL_TEXTURE_2D, texture_.id());
  glBindVertexArray(vertex_array_);
  glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
  glBindVertexArray(0);
  glBindTexture(GL_TEXTURE_2D, static_cast<GLuint>(previous_texture));
  glUseProgram(0);
}

void FeedPanel::draw_tracked_points(const TrajectoryView& view) {
  const std::size_t n = std::min(view.current_pixels.size(), view.current_depths.size());
  if (n == 0) return;
  // Inverse depth over its 5-95 % range: near points red, far ones blue, whatever the scale.
  float lo = std::numeric_limits<float>::max();
  float hi = 0.0f;
  for (std::size_t i = 0; i < n; ++i) {
    const float inverse_depth = 1.0f / std::max(view.current_depths[i], 1e-6f);
    lo = std::min(lo, inverse_depth);
    hi = std::max(hi, inverse_depth);
  }
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const float radius = std::clamp(1.5f * scale_, 1.5f, 4.0f);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2f& p = view.current_pixels[i];
    const ImVec2 screen(image_.min.x + (p.x() + 0.5f) * scale_, image_.min.y + (p.y() + 0.5f) * scale_);
    if (!view_.contains(screen)) continue;
    const float inverse_depth = 1.0f / std::max(view.current_depths[i], 1e-6f);
    const float t = hi > lo ? (inverse_depth - lo) / (hi - lo) : 0.5f;
    draw->AddCircleFilled(screen, radius, time_colour(t), 6);
    ++points_drawn_;
  }
}

void FeedPanel::draw_overlays(const Snapshot& snapshot, const Frame& frame, bool hovered) {
  ImDrawList* draw = ImGui::GetWindowDrawList();

  std::vector<OverlayRow> info;
  info.push_back({"Frame", fmt::format("#{}", frame.index)});
  info.push_back({"Time", fmt::format("{:.3f} s", frame.timestamp_s)});
  info.push_back({"Size", fmt::format("{} × {} px", frame.width(), frame.height())});
  info.push_back({"Depth", depth_text(frame)});
  info.push_back({"Exposure", frame.exposure_ms ? fmt::format("{:.2f} ms", *frame.exposure_ms) : "unknown",
                  frame.exposure_ms ? 0u : colours::text_dim});
  if (frame.gain) info.push_back({"Gain", fmt::format("{:.2f}×", *frame.gain)});
  const auto power = frame.illuminator_power_w ? frame.illuminator_power_w : snapshot.illuminator_power_w;
  if (power) info.push_back({"Illuminator", fmt::format("{:.1f} W", *power)});
  if (show_info) draw_overlay_table(draw, view_, Corner::TopLeft, info);

  std::vector<OverlayRow> rate;
  rate.push_back({"Processing", fmt::format("{:.1f} fps", snapshot.processing_fps)});
  rate.push_back({"Frame time", fmt::format("{:.2f} ms", snapshot.timings.total_ms)});
  rate.push_back({"Dropped", fmt::format("{}", snapshot.frames_dropped),
                  snapshot.frames_dropped > 0 ? colours::state_paused : 0u});
  if (show_info) draw_overlay_table(draw, view_, Corner::TopRight, rate);

  if (hovered && scale_ > 0.0f) {
    const ImVec2 mouse = ImGui::GetIO().MousePos;
    const int x = static_cast<int>(std::floor((mouse.x - image_.min.x) / scale_));
    const int y = static_cast<int>(std::floor((mouse.y - image_.min.y) / scale_));
    if (x >= 0 && y >= 0 && x < frame.width() && y < frame.height()) {
      const std::uint32_t code = pixel_code(frame.image, x, y);
      const std::uint32_t top = frame.max_value();
      const ImU32 colour = code >= top ? colours::saturated : code == 0 ? colours::black : 0u;
      draw_overlay_table(draw, view_, Corner::BottomLeft,
                         {{"Pixel", fmt::format("x {}, y {}", x, y)},
                          {"Value", fmt::format("{} / {} ({:.1f} %)", code, top, 100.0 * code / top), colour}});
    }
  }
}

}  // namespace nirslam::ui
