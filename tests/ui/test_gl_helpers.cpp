// GL helpers: shader lookup order and errors that name the file and carry the GLSL log; grey
// texture uploads; offscreen framebuffer read-back orientation.

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>

#include <gtest/gtest.h>
#include <unistd.h>

#include "ui/gl/framebuffer.hpp"
#include "ui/gl/shader.hpp"
#include "ui/gl/texture.hpp"
#include "ui/ui_test_support.hpp"

namespace nirslam::ui::gl {
namespace {

class ScopedEnv {
public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    ::setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (old_)
      ::setenv(name_, old_->c_str(), 1);
    else
      ::unsetenv(name_);
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

private:
  const char* name_;
  std::optional<std::string> old_;
};

std::filesystem::path temp_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir;
}

void write(const std::filesystem::path& path, const std::string& text) { std::ofstream(path) << text; }

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(ShaderLookup, FindsTheSourceTreeShadersByDefault) {
  const auto dir = find_shader_dir();
  EXPECT_TRUE(std::filesystem::is_regular_file(dir / "image_quad.vert")) << dir;
  EXPECT_TRUE(std::filesystem::is_regular_file(dir / "image_quad.frag")) << dir;
}

TEST(ShaderLookup, EnvironmentVariableComesFirst) {
  const auto dir = temp_dir("nirslam_shader_env");
  {
    ScopedEnv env("NIRSLAM_SHADER_DIR", dir.string());
    EXPECT_EQ(find_shader_dir(), dir);
    const auto candidates = shader_dir_candidates();
    ASSERT_GE(candidates.size(), 3u);
    EXPECT_EQ(candidates.front(), dir);
    EXPECT_EQ(candidates[1].filename(), "shaders");  // <exe>/../share/nirslam/shaders
    EXPECT_TRUE(contains(candidates[1].string(), "share/nirslam")) << candidates[1];
  }
  {
    ScopedEnv env("NIRSLAM_SHADER_DIR", (dir / "nowhere").string());
    try {
      find_shader_dir();
      ADD_FAILURE() << "expected ShaderError";
    } catch (const ShaderError& e) {
      EXPECT_TRUE(contains(e.what(), "NIRSLAM_SHADER_DIR")) << e.what();
      EXPECT_TRUE(contains(e.what(), (dir / "nowhere").string())) << e.what();
    }
  }
  std::filesystem::remove_all(dir);
}

class ShaderProgramTest : public ui::testing::HeadlessGlTest {};

TEST_F(ShaderProgramTest, MissingFileErrorNamesThePath) {
  const auto dir = temp_dir("nirslam_shader_missing");
  try {
    load_program(dir, "image_quad");
    ADD_FAILURE() << "expected ShaderError";
  } catch (const ShaderError& e) {
    EXPECT_TRUE(contains(e.what(), "not found")) << e.what();
    EXPECT_TRUE(contains(e.what(), (dir / "image_quad.vert").string())) << e.what();
  }
  std::filesystem::remove_all(dir);
}

TEST_F(ShaderProgramTest, CompileErrorNamesTheFileAndCarriesTheGlslLog) {
  const auto dir = temp_dir("nirslam_shader_broken");
  write(dir / "broken.vert", "#version 330 core\nvoid main() { gl_Position = vec4(0.0); }\n");
  write(dir / "broken.frag", "#version 330 core\nout vec4 c;\nvoid main() { c = vec4(undeclared_thing, 1.0); }\n");
  try {
    load_program(dir, "broken");
    ADD_FAILURE() << "expected ShaderError";
  } catch (const ShaderError& e) {
    EXPECT_TRUE(contains(e.what(), (dir / "broken.frag").string())) << e.what();
    EXPECT_TRUE(contains(e.what(), "undeclared_thing")) << "the GLSL log: " << e.what();
  }
  std::filesystem::remove_all(dir);
}

TEST_F(ShaderProgramTest, ProjectShadersCompileAndLink) {
  const Program program = load_program(find_shader_dir(), "image_quad");
  EXPECT_TRUE(program.valid());
  EXPECT_GE(program.uniform("u_max_code"), 0);
  EXPECT_GE(program.uniform("u_highlight_clipping"), 0);
}

TEST_F(ShaderProgramTest, GreyTextureKeepsSizeAndDepth) {
  GreyTexture texture;
  EXPECT_TRUE(texture.empty());
  texture.upload(cv::Mat(30, 40, CV_8UC1, cv::Scalar(7)));
  EXPECT_EQ(texture.width(), 40);
  EXPECT_EQ(texture.height(), 30);
  EXPECT_FALSE(texture.sixteen_bit());
  EXPECT_EQ(texture.container_max(), 255.0f);
  const cv::Mat big(100, 50, CV_16UC1, cv::Scalar(1000));
  texture.upload(big(cv::Rect(5, 5, 21, 13)));  // an ROI with a row stride wider than its width
  EXPECT_EQ(texture.width(), 21);
  EXPECT_EQ(texture.height(), 13);
  EXPECT_TRUE(texture.sixteen_bit());
  EXPECT_EQ(glGetError(), static_cast<GLenum>(GL_NO_ERROR));
  EXPECT_THROW(texture.upload(cv::Mat(4, 4, CV_32FC1)), std::invalid_argument);
  EXPECT_THROW(texture.upload(cv::Mat(4, 4, CV_8UC3)), std::invalid_argument);
}

TEST_F(ShaderProgramTest, FramebufferReadsBackTopRowFirst) {
  Framebuffer fb;
  fb.resize(64, 32);
  FramebufferBindingGuard guard;
  fb.bind();
  glDisable(GL_SCISSOR_TEST);
  glClearColor(0.0f, 0.0f, 1.0f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  // GL's origin is bottom-left: paint the bottom 8 GL rows red.
  glEnable(GL_SCISSOR_TEST);
  glScissor(0, 0, 64, 8);
  glClearColor(1.0f, 0.0f, 0.0f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  glDisable(GL_SCISSOR_TEST);
  const cv::Mat rgba = fb.read_rgba();
  ASSERT_EQ(rgba.cols, 64);
  ASSERT_EQ(rgba.rows, 32);
  EXPECT_EQ(rgba.at<cv::Vec4b>(31, 10), cv::Vec4b(255, 0, 0, 255)) << "bottom row of the image is red";
  EXPECT_EQ(rgba.at<cv::Vec4b>(0, 10), cv::Vec4b(0, 0, 255, 255)) << "top row is blue";
  EXPECT_THROW(fb.resize(0, 10), std::runtime_error);
}

}  // namespace
}  // namespace nirslam::ui::gl
