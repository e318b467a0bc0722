#include "ui/theme.hpp"

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

namespace nirslam::ui {
namespace {

Fonts g_fonts;

std::string find_font(const char* env_name, const std::vector<const char*>& candidates) {
  std::error_code error;
  if (const char* env = std::getenv(env_name); env != nullptr && std::filesystem::is_regular_file(env, error))
    return env;
  for (const char* path : candidates)
    if (std::filesystem::is_regular_file(path, error)) return path;
  return {};
}

}  // namespace

ImVec4 to_vec4(ImU32 colour) {
  return ImVec4(static_cast<float>(colour & 0xFFu) / 255.0f, static_cast<float>((colour >> 8) & 0xFFu) / 255.0f,
                static_cast<float>((colour >> 16) & 0xFFu) / 255.0f, static_cast<float>((colour >> 24) & 0xFFu) / 255.0f);
}

const Fonts& fonts() { return g_fonts; }

const Fonts& load_fonts(float scale) {
  ImGuiIO& io = ImGui::GetIO();
  io.Fonts->Clear();
  g_fonts = {};
  // Latin-1 plus general punctuation (dashes, bullets), arrows, math operators and geometric shapes.
  static const ImWchar ranges[] = {0x0020, 0x00FF, 0x2010, 0x2027, 0x2190, 0x21FF,
                                   0x2212, 0x2265, 0x25A0, 0x25FF, 0};
  const std::string sans = find_font("NIRSLAM_FONT", {"/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
                                                     "/usr/share/fonts/truetype/noto/NotoSans-Regular.ttf",
                                                     "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf"});
  const std::string mono = find_font("NIRSLAM_MONO_FONT", {"/usr/share/fonts/truetype/dejavu/DejaVuSansMono.ttf",
                                                           "/usr/share/fonts/truetype/noto/NotoSansMono-Regular.ttf"});
  ImFontConfig config;
  config.OversampleH = 2;
  config.OversampleV = 2;
  if (!sans.empty()) {
    g_fonts.regular = io.Fonts->AddFontFromFileTTF(sans.c_str(), 15.0f * scale, &config, ranges);
    g_fonts.large = io.Fonts->AddFontFromFileTTF(sans.c_str(), 30.0f * scale, &config, ranges);
    g_fonts.scalable = g_fonts.regular != nullptr && g_fonts.large != nullptr;
  }
  if (!g_fonts.scalable) {
    ImFontConfig fallback;
    fallback.SizePixels = 13.0f * scale;
    g_fonts.regular = io.Fonts->AddFontDefault(&fallback);
    fallback.SizePixels = 26.0f * scale;
    g_fonts.large = io.Fonts->AddFontDefault(&fallback);
  }
  g_fonts.mono = !mono.empty() ? io.Fonts->AddFontFromFileTTF(mono.c_str(), 14.0f * scale, &config, ranges) : nullptr;
  if (g_fonts.mono == nullptr) g_fonts.mono = g_fonts.regular;
  io.FontDefault = g_fonts.regular;
  return g_fonts;
}

void apply_style(float scale) {
  ImGuiStyle& style = ImGui::GetStyle();
  style = ImGuiStyle();
  style.WindowPadding = ImVec2(10, 8);
  style.FramePadding = ImVec2(8, 4);
  style.ItemSpacing = ImVec2(8, 6);
  style.ItemInnerSpacing = ImVec2(6, 4);
  style.WindowRounding = 0.0f;
  style.ChildRounding = 3.0f;
  style.FrameRounding = 3.0f;
  style.GrabRounding = 3.0f;
  style.PopupRounding = 3.0f;
  style.ScrollbarRounding = 3.0f;
  style.WindowBorderSize = 1.0f;
  style.FrameBorderSize = 0.0f;
  style.WindowTitleAlign = ImVec2(0.0f, 0.5f);
  style.ScaleAllSizes(scale);

  ImVec4* c = style.Colors;
  c[ImGuiCol_Text] = to_vec4(colours::text);
  c[ImGuiCol_TextDisabled] = to_vec4(colours::text_dim);
  c[ImGuiCol_WindowBg] = to_vec4(colours::window_bg);
  c[ImGuiCol_ChildBg] = to_vec4(colours::panel_bg);
  c[ImGuiCol_PopupBg] = to_vec4(rgba(36, 39, 45, 250));
  c[ImGuiCol_Border] = to_vec4(colours::border);
  c[ImGuiCol_BorderShadow] = ImVec4(0, 0, 0, 0);
  c[ImGuiCol_FrameBg] = to_vec4(colours::frame_bg);
  c[ImGuiCol_FrameBgHovered] = to_vec4(rgba(54, 60, 70));
  c[ImGuiCol_FrameBgActive] = to_vec4(rgba(62, 69, 80));
  c[ImGuiCol_TitleBg] = to_vec4(rgba(22, 24, 28));
  c[ImGuiCol_TitleBgActive] = to_vec4(rgba(22, 24, 28));
  c[ImGuiCol_TitleBgCollapsed] = to_vec4(rgba(22, 24, 28));
  c[ImGuiCol_MenuBarBg] = to_vec4(rgba(26, 28, 33));
  c[ImGuiCol_ScrollbarBg] = to_vec4(rgba(26, 28, 33));
  c[ImGuiCol_ScrollbarGrab] = to_vec4(rgba(66, 72, 82));
  c[ImGuiCol_ScrollbarGrabHovered] = to_vec4(rgba(80, 87, 98));
  c[ImGuiCol_ScrollbarGrabActive] = to_vec4(rgba(92, 100, 112));
  c[ImGuiCol_CheckMark] = to_vec4(colours::accent);
  c[ImGuiCol_SliderGrab] = to_vec4(colours::accent);
  c[ImGuiCol_SliderGrabActive] = to_vec4(rgba(100, 170, 240));
  c[ImGuiCol_Button] = to_vec4(rgba(50, 55, 64));
  c[ImGuiCol_ButtonHovered] = to_vec4(rgba(62, 90, 128));
  c[ImGuiCol_ButtonActive] = to_vec4(rgba(70, 110, 160));
  c[ImGuiCol_Header] = to_vec4(rgba(50, 55, 64));
  c[ImGuiCol_HeaderHovered] = to_vec4(rgba(62, 90, 128));
  c[ImGuiCol_HeaderActive] = to_vec4(rgba(70, 110, 160));
  c[ImGuiCol_Separator] = to_vec4(colours::border);
  c[ImGuiCol_ResizeGrip] = ImVec4(0, 0, 0, 0);
  c[ImGuiCol_Tab] = to_vec4(rgba(36, 39, 45));
  c[ImGuiCol_TabHovered] = to_vec4(rgba(62, 90, 128));
  c[ImGuiCol_TabActive] = to_vec4(rgba(50, 55, 64));
  c[ImGuiCol_PlotLines] = to_vec4(colours::entropy);
  c[ImGuiCol_PlotHistogram] = to_vec4(colours::entropy);
  c[ImGuiCol_TableHeaderBg] = to_vec4(rgba(36, 39, 45));
  c[ImGuiCol_TableBorderStrong] = to_vec4(colours::border);
  c[ImGuiCol_TableBorderLight] = to_vec4(rgba(44, 48, 56));
  c[ImGuiCol_TableRowBg] = ImVec4(0, 0, 0, 0);
  c[ImGuiCol_TableRowBgAlt] = to_vec4(rgba(255, 255, 255, 8));
  c[ImGuiCol_TextSelectedBg] = to_vec4(rgba(70, 150, 230, 90));
  c[ImGuiCol_NavHighlight] = to_vec4(colours::accent);
}

}  // namespace nirslam::ui
