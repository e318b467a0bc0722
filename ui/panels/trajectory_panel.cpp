#include "ui/panels/trajectory_panel.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Geometry>
#include <fmt/format.h>

#include "ui/colour_maps.hpp"
#include "ui/gl/texture.hpp"
#include "ui/theme.hpp"

namespace nirslam::ui {
namespace {

constexpr ImU32 kGroundTruth = rgba(200, 204, 212, 150);
constexpr ImU32 kKeyframe = rgba(70, 150, 230);
constexpr ImU32 kGrid = rgba(52, 57, 66);
constexpr ImU32 kGridAxis = rgba(78, 84, 96);

// 1, 2 or 5 x 10^k, the largest not above `value`.
float nice_step(float value) {
  const float decade = std::pow(10.0f, std::floor(std::log10(std::max(value, 1e-6f))));
  for (float m : {5.0f, 2.0f, 1.0f})
    if (m * decade <= value) return m * decade;
  return decade;
}

std::string metres_text(double metres) {
  if (metres < 0.01) return fmt::format("{:.1f} mm", 1000.0 * metres);
  if (metres < 1.0) return fmt::format("{:.1f} cm", 100.0 * metres);
  return fmt::format("{:.2f} m", metres);
}

// A camera frustum: apex at the centre, the image rectangle `size` ahead (4:3).
void add_frustum(gl::VertexBatch& lines, const PoseSample& pose, float size, ImU32 colour) {
  const Eigen::Matrix3f R = pose.rotation.toRotationMatrix();
  const Eigen::Vector3f& c = pose.position;
  const float w = 0.5f * size * 4.0f / 3.0f;
  const float h = 0.5f * size;
  const Eigen::Vector3f corners[4] = {c + R * Eigen::Vector3f(-w, -h, size), c + R * Eigen::Vector3f(w, -h, size),
                                      c + R * Eigen::Vector3f(w, h, size), c + R * Eigen::Vector3f(-w, h, size)};
  for (int i = 0; i < 4; ++i) {
    lines.add_line(c, corners[i], colour);
    lines.add_line(corners[i], corners[(i + 1) % 4], colour);
  }
  // A tick on the top edge says which way is up in the image.
  lines.add_line(0.5f * (corners[0] + corners[1]), c + R * Eigen::Vector3f(0.0f, -h * 1.5f, size), colour);
}

}  // namespace

TrajectoryPanel::TrajectoryPanel(const std::filesystem::path& shader_dir)
    : program_(gl::load_program(shader_dir, "scene")) {
  u_view_projection_ = program_.uniform("u_view_projection");
  u_point_size_ = program_.uniform("u_point_size");
  u_round_points_ = program_.uniform("u_round_points");
}

void TrajectoryPanel::fit_all() {
  fit_pending_ = true;
  auto_fit_ = true;
}

void TrajectoryPanel::draw(const Snapshot& snapshot) {
  const TrajectoryView* view = snapshot.trajectory ? snapshot.trajectory.get() : nullptr;
  draw_tool_row(view);

  const ImVec2 avail = ImGui::GetContentRegionAvail();
  view_.min = ImGui::GetCursorScreenPos();
  view_.max = ImVec2(view_.min.x + std::floor(avail.x), view_.min.y + std::floor(avail.y));
  if (view_.width() < 16.0f || view_.height() < 16.0f) return;
  ImGui::InvisibleButton("##view3d", view_.size(), ImGuiButtonFlags_MouseButtonLeft |
                                                      ImGuiButtonFlags_MouseButtonRight |
                                                      ImGuiButtonFlags_MouseButtonMiddle);
  const bool hovered = ImGui::IsItemHovered();
  const bool active = ImGui::IsItemActive();
  ImDrawList* draw = ImGui::GetWindowDrawList();

  if (view == nullptr || view->poses.empty()) {
    draw->AddRectFilled(view_.min, view_.max, colours::feed_bg);
    const char* line1 = view != nullptr && view->enabled ? "No pose yet" : "Odometry off";
    const std::string line2 = view == nullptr || !view->enabled ? std::string("this pipeline mode has no odometry")
                              : !view->message.empty()          ? view->message
                                                                : std::string("initialising: move the camera sideways");
    const ImVec2 s1 = ImGui::CalcTextSize(line1);
    const ImVec2 s2 = ImGui::CalcTextSize(line2.c_str());
    const ImVec2 c = view_.centre();
    draw->AddText(ImVec2(c.x - 0.5f * s1.x, c.y - s1.y - 2.0f), colours::text, line1);
    draw->AddText(ImVec2(c.x - 0.5f * s2.x, c.y + 2.0f), colours::text_dim, line2.c_str());
    fit_pending_ = true;
    auto_fit_ = true;
    up_known_ = false;
    return;
  }

  rebuild(*view);
  handle_input(hovered, active);
  if (follow && view->current) camera_.target = view->current->position;
  shown_view_ = snapshot.trajectory;
  render();
  draw->AddImage(gl::texture_id(target_.texture()), view_.min, view_.max, ImVec2(0.0f, 1.0f), ImVec2(1.0f, 0.0f));
  draw->PushClipRect(view_.min, view_.max, true);
  draw_overlays(*view);
  draw->PopClipRect();
}

void TrajectoryPanel::draw_tool_row(const TrajectoryView* view) {
  // The row wraps in a narrow panel instead of running under the border.
  const ImGuiStyle& style = ImGui::GetStyle();
  const float right = ImGui::GetWindowContentRegionMax().x;
  bool first = true;
  const auto place = [&](float item_width) {
    if (!first && ImGui::GetItemRectMax().x - ImGui::GetWindowPos().x + style.ItemSpacing.x + item_width <= right)
      ImGui::SameLine();
    first = false;
  };
  const auto button_width = [&](const char* label) { return ImGui::CalcTextSize(label).x + 2.0f * style.FramePadding.x; };
  const auto checkbox_width = [&](const char* label) {
    return ImGui::GetFrameHeight() + style.ItemInnerSpacing.x + ImGui::CalcTextSize(label).x;
  };

  place(button_width("Fit"));
  if (ImGui::Button("Fit")) fit_all();
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("Frame the whole trajectory (double-click in the view)");
  place(button_width("Top"));
  if (ImGui::Button("Top")) top_view();
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("Look straight down onto the ground plane");
  place(checkbox_width("Follow"));
  ImGui::Checkbox("Follow", &follow);
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("Keep the current camera at the centre of the view");
  place(checkbox_width("Points"));
  ImGui::Checkbox("Points", &show_points);
  place(checkbox_width("Keyframes"));
  ImGui::Checkbox("Keyframes", &show_keyframes);
  if (view != nullptr && !view->ground_truth.empty()) {
    place(checkbox_width("Ground truth"));
    ImGui::Checkbox("Ground truth", &show_ground_truth);
  }
  const float combo_width = ImGui::CalcTextSize("Colour: error").x + ImGui::GetFrameHeight() * 1.6f;
  place(combo_width);
  int mode = colouring == Colouring::Error ? 1 : 0;
  ImGui::SetNextItemWidth(combo_width);
  if (ImGui::Combo("##colouring", &mode, "Colour: time\0Colour: error\0"))
    colouring = mode == 1 ? Colouring::Error : Colouring::Time;
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip("Colour the path by time, or by its distance to the aligned ground truth (when known)");
}

void TrajectoryPanel::handle_input(bool hovered, bool active) {
  const ImGuiIO& io = ImGui::GetIO();
  if (hovered && ImGui::IsMouseDoubleClicked(ImGuiMouseButton_Left)) fit_all();
  if (active) {
    const bool panning = ImGui::IsMouseDragging(ImGuiMouseButton_Right, 0.0f) ||
                         ImGui::IsMouseDragging(ImGuiMouseButton_Middle, 0.0f) ||
                         (io.KeyShift && ImGui::IsMouseDragging(ImGuiMouseButton_Left, 0.0f));
    if (panning) {
      camera_.pan(io.MouseDelta.x, io.MouseDelta.y, view_.height());
      follow = false;
      auto_fit_ = false;
    } else if (ImGui::IsMouseDragging(ImGuiMouseButton_Left, 0.0f)) {
      camera_.orbit(io.MouseDelta.x, io.MouseDelta.y);
    }
  }
  if (hovered && io.MouseWheel != 0.0f) {
    camera_.zoom(io.MouseWheel);
    auto_fit_ = false;
  }
}

void TrajectoryPanel::rebuild(const TrajectoryView& view) {
  // Bounds of the path (points can hold far outliers, so they do not set the frame).
  Eigen::Vector3f lo = view.poses.front().position;
  Eigen::Vector3f hi = lo;
  for (const PoseSample& p : view.poses) {
    lo = lo.cwiseMin(p.position);
    hi = hi.cwiseMax(p.position);
  }
  if (show_ground_truth)
    for (const Eigen::Vector3f& g : view.ground_truth) {
      lo = lo.cwiseMin(g);
      hi = hi.cwiseMax(g);
    }
  const Eigen::Vector3f centre = 0.5f * (lo + hi);
  scene_radius_ = std::max(0.5f * (hi - lo).norm(), 1e-3f);

  if (!up_known_) {
    // Monocular odometry has no gravity: the first camera's "up" (-y) is the best guess, and it is
    // also right for a ground-truth-aligned estimate of a level rig.
    const Eigen::Vector3f up = view.poses.front().rotation * Eigen::Vector3f(0.0f, -1.0f, 0.0f);
    camera_.up = up.normalized();
    up_known_ = true;
  }
  // Auto-framing follows a growing path in steps (with 25 % slack) rather than every frame: the
  // view stays calm, and a still camera lets render() reuse the points layer.
  const bool outgrown = (centre - framed_centre_).norm() + scene_radius_ > framed_radius_ ||
                        scene_radius_ < 0.5f * framed_radius_;
  if (fit_pending_ || (auto_fit_ && !follow && outgrown)) {
    framed_centre_ = centre;
    framed_radius_ = fit_pending_ ? scene_radius_ : 1.25f * scene_radius_;
    camera_.frame(centre, framed_radius_);
    fit_pending_ = false;
  }

  by_error_ = colouring == Colouring::Error &&
              std::any_of(view.poses.begin(), view.poses.end(), [](const PoseSample& p) { return p.error_m >= 0.0f; });
  max_error_ = 0.0f;
  if (by_error_)
    for (const PoseSample& p : view.poses) max_error_ = std::max(max_error_, p.error_m);

  lines_.clear();
  // Ground grid through the lowest pose, perpendicular to up.
  {
    const Eigen::Vector3f up = camera_.up.normalized();
    float lowest = up.dot(view.poses.front().position);
    for (const PoseSample& p : view.poses) lowest = std::min(lowest, up.dot(p.position));
    const Eigen::Vector3f seed = std::abs(up.x()) < 0.9f ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitY();
    const Eigen::Vector3f a = (seed - seed.dot(up) * up).normalized();
    const Eigen::Vector3f b = up.cross(a);
    const float step = nice_step(scene_radius_ / 4.0f);
    const int half = 10;
    const Eigen::Vector3f origin = centre - (up.dot(centre) - lowest) * up;
    const Eigen::Vector3f snapped = origin - std::fmod(a.dot(origin), step) * a - std::fmod(b.dot(origin), step) * b;
    for (int i = -half; i <= half; ++i) {
      const ImU32 colour = i == 0 ? kGridAxis : kGrid;
      lines_.add_line(snapped + (i * step) * a - (half * step) * b, snapped + (i * step) * a + (half * step) * b, colour);
      lines_.add_line(snapped + (i * step) * b - (half * step) * a, snapped + (i * step) * b + (half * step) * a, colour);
    }
  }
  if (show_ground_truth)
    for (std::size_t i = 1; i < view.ground_truth.size(); ++i)
      lines_.add_line(view.ground_truth[i - 1], view.ground_truth[i], kGroundTruth);

  const float n = static_cast<float>(std::max<std::size_t>(view.poses.size() - 1, 1));
  const auto pose_colour = [&](std::size_t i) {
    const PoseSample& p = view.poses[i];
    if (by_error_) return error_colour(p.error_m >= 0.0f && max_error_ > 0.0f ? p.error_m / max_error_ : 0.0f);
    return time_colour(static_cast<float>(i) / n);
  };
  for (std::size_t i = 1; i < view.poses.size(); ++i) {
    if (view.poses[i].segment != view.poses[i - 1].segment) continue;  // a loss: no line across it
    lines_.add(view.poses[i - 1].position, pose_colour(i - 1));
    lines_.add(view.poses[i].position, pose_colour(i));
  }
  const float frustum = 0.06f * scene_radius_;
  if (show_keyframes)
    for (const PoseSample& k : view.keyframes) add_frustum(lines_, k, frustum, kKeyframe);
  if (view.current) {
    const bool lost = view.tracking == "lost";
    add_frustum(lines_, *view.current, 1.8f * frustum, lost ? colours::state_failed : colours::state_running);
  }
  lines_.upload();

  markers_.clear();
  for (std::size_t i = 0; i < view.poses.size(); ++i) markers_.add(view.poses[i].position, pose_colour(i));
  markers_.upload();

  if (view.points != uploaded_points_) {
    points_.clear();
    if (view.points) {
      points_.vertices().reserve(view.points->size());
      for (const MapPointSample& p : *view.points) {
        const float g = std::clamp(p.intensity / 255.0f, 0.0f, 1.0f);
        const auto level = [](float x) { return static_cast<unsigned>(std::lround(255.0f * std::clamp(x, 0.0f, 1.0f))); };
        // Active points in warm tint (what the window optimises now), marginalised ones grey.
        const ImU32 colour = p.active ? rgba(level(0.35f + 0.65f * g), level(0.25f + 0.55f * g), level(0.1f + 0.3f * g))
                                      : rgba(level(0.2f + 0.6f * g), level(0.2f + 0.6f * g), level(0.22f + 0.6f * g));
        points_.add(p.position, colour);
      }
    }
    points_.upload();
    uploaded_points_ = view.points;
  }
}

void TrajectoryPanel::render_points_layer(const RenderKey& key) {
  RenderKey layer = key;
  layer.view = nullptr;  // the layer depends on the points, not on the poses
  layer.keyframes = false;
  layer.ground_truth = false;
  layer.colouring = Colouring::Time;
  const bool same_points = uploaded_points_ == points_uploaded_for_layer_;
  if (layer == points_rendered_ && same_points) return;
  points_rendered_ = layer;
  points_uploaded_for_layer_ = uploaded_points_;
  points_layer_.resize(key.target_w, key.target_h, true);

  points_layer_.bind();
  const ImVec4 bg = to_vec4(colours::feed_bg);
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_BLEND);
  glDisable(GL_CULL_FACE);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LEQUAL);
  glEnable(GL_PROGRAM_POINT_SIZE);
  glClearColor(bg.x, bg.y, bg.z, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  if (show_points) {
    const float size = point_size * ImGui::GetIO().DisplayFramebufferScale.x;
    program_.use();
    glUniformMatrix4fv(u_view_projection_, 1, GL_FALSE, key.view_projection.data());
    // Round sprites cost a discard per fragment on a software rasteriser; at 2 px they would
    // look square anyway.
    glUniform1i(u_round_points_, size >= 3.0f ? 1 : 0);
    glUniform1f(u_point_size_, size);
    points_.draw();
  }
}

void TrajectoryPanel::render() {
  const ImVec2 fb_scale = ImGui::GetIO().DisplayFramebufferScale;
  const int target_w = std::max(1, static_cast<int>(std::lround(view_.width() * fb_scale.x)));
  const int target_h = std::max(1, static_cast<int>(std::lround(view_.height() * fb_scale.y)));
  view_projection_ = camera_.view_projection(view_.width() / view_.height());
  const RenderKey key{shown_view_.get(), show_points, show_keyframes, show_ground_truth, colouring, point_size,
                      target_w, target_h, view_projection_};
  if (key == rendered_) return;
  rendered_ = key;
  target_.resize(target_w, target_h, true);
  gl::FramebufferBindingGuard guard;
  render_points_layer(key);

  target_.bind();
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_BLEND);
  glDisable(GL_CULL_FACE);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LEQUAL);
  glEnable(GL_PROGRAM_POINT_SIZE);
  // The points layer (colour and depth) is the background the path is drawn into.
  glBindFramebuffer(GL_READ_FRAMEBUFFER, points_layer_.id());
  glBlitFramebuffer(0, 0, target_w, target_h, 0, 0, target_w, target_h, GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT,
                    GL_NEAREST);
  target_.bind();

  program_.use();
  glUniformMatrix4fv(u_view_projection_, 1, GL_FALSE, view_projection_.data());  // Eigen is column-major, as GL
  glUniform1i(u_round_points_, 0);
  glUniform1f(u_point_size_, 1.0f);
  lines_.draw();
  glUniform1i(u_round_points_, 1);
  glUniform1f(u_point_size_, 4.0f * fb_scale.x);
  markers_.draw();

  glUseProgram(0);
  glDisable(GL_PROGRAM_POINT_SIZE);
  glDisable(GL_DEPTH_TEST);
}

std::optional<ImVec2> TrajectoryPanel::project(const Eigen::Vector3f& world) const {
  const Eigen::Vector4f clip = view_projection_ * world.homogeneous();
  if (clip.w() <= 1e-6f) return std::nullopt;
  const float x = clip.x() / clip.w();
  const float y = clip.y() / clip.w();
  return ImVec2(view_.min.x + (0.5f * x + 0.5f) * view_.width(), view_.min.y + (0.5f - 0.5f * y) * view_.height());
}

void TrajectoryPanel::draw_overlays(const TrajectoryView& view) {
  ImDrawList* draw = ImGui::GetWindowDrawList();
  std::vector<OverlayRow> rows;
  const bool lost = view.tracking == "lost";
  rows.push_back({"Tracking", view.tracking.empty() ? "–" : view.tracking,
                  lost ? colours::state_failed : view.tracking == "tracking" ? colours::state_running : colours::state_paused});
  if (view.segment > 0) rows.push_back({"Segment", fmt::format("{} (after a loss)", view.segment + 1), colours::state_paused});
  rows.push_back({"Poses", fmt::format("{}", view.poses.size())});
  rows.push_back({"Keyframes", fmt::format("{}", view.keyframes.size())});
  rows.push_back({"Points", fmt::format("{}", view.points ? view.points->size() : 0)});
  const std::string unit = view.aligned_to_ground_truth ? "" : " (no scale)";
  rows.push_back({"Path", view.aligned_to_ground_truth ? metres_text(view.path_length)
                                                        : fmt::format("{:.2f}{}", view.path_length, unit)});
  if (view.ate_rmse_m) rows.push_back({"ATE RMSE", metres_text(*view.ate_rmse_m)});
  if (!view.message.empty() && (lost || view.tracking != "tracking")) rows.push_back({"", view.message, colours::text_dim});
  draw_overlay_table(draw, view_, Corner::TopLeft, rows);

  // Colour legend: the error scale, or the time ramp. Title, bar, end labels under it.
  const float bar_w = std::min(180.0f, 0.4f * view_.width());
  const float bar_h = 8.0f;
  const float pad = 8.0f;
  const float line = ImGui::GetTextLineHeight();
  const ImVec2 box_max(view_.max.x - pad, view_.max.y - pad);
  const ImVec2 box_min(box_max.x - bar_w - 2.0f * pad, box_max.y - 2.0f * line - bar_h - 3.0f * pad);
  draw->AddRectFilled(box_min, box_max, colours::overlay_bg, 4.0f);
  const char* title = by_error_ ? "Error to ground truth" : "Time";
  draw->AddText(ImVec2(box_min.x + pad, box_min.y + pad), colours::text_dim, title);
  const ImVec2 bar_min(box_min.x + pad, box_min.y + pad + line + pad * 0.5f);
  constexpr int kSteps = 32;
  for (int i = 0; i < kSteps; ++i) {
    const float t = static_cast<float>(i) / (kSteps - 1);
    const float x0 = bar_min.x + bar_w * static_cast<float>(i) / kSteps;
    draw->AddRectFilled(ImVec2(x0, bar_min.y), ImVec2(x0 + bar_w / kSteps + 0.5f, bar_min.y + bar_h),
                        by_error_ ? error_colour(t) : time_colour(t));
  }
  const std::string left = by_error_ ? "0" : "start";
  const std::string right = by_error_ ? metres_text(max_error_) : "now";
  const float label_y = bar_min.y + bar_h + pad * 0.5f;
  draw->AddText(ImVec2(bar_min.x, label_y), colours::text, left.c_str());
  draw->AddText(ImVec2(bar_min.x + bar_w - ImGui::CalcTextSize(right.c_str()).x, label_y), colours::text, right.c_str());
}

}  // namespace nirslam::ui
