#include "ui/gl/shader.hpp"

#include "nirslam/common/resource_paths.hpp"

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <system_error>
#include <utility>

namespace nirslam::ui::gl {
namespace {

std::string read_text(const std::filesystem::path& path) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error))
    throw ShaderError("shader file not found: " + path.string());
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ShaderError("cannot read shader file: " + path.string());
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::string shader_log(GLuint shader) {
  GLint length = 0;
  glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<std::size_t>(length > 0 ? length : 0), '\0');
  if (length > 0) glGetShaderInfoLog(shader, length, nullptr, log.data());
  while (!log.empty() && (log.back() == '\0' || log.back() == '\n')) log.pop_back();
  return log;
}

std::string program_log(GLuint program) {
  GLint length = 0;
  glGetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<std::size_t>(length > 0 ? length : 0), '\0');
  if (length > 0) glGetProgramInfoLog(program, length, nullptr, log.data());
  while (!log.empty() && (log.back() == '\0' || log.back() == '\n')) log.pop_back();
  return log;
}

GLuint compile(GLenum kind, const std::string& source, const std::string& name) {
  const GLuint shader = glCreateShader(kind);
  if (shader == 0) throw ShaderError("glCreateShader failed for " + name + " (is a GL context current?)");
  const char* text = source.c_str();
  const auto length = static_cast<GLint>(source.size());
  glShaderSource(shader, 1, &text, &length);
  glCompileShader(shader);
  GLint ok = GL_FALSE;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE) {
    const std::string log = shader_log(shader);
    glDeleteShader(shader);
    throw ShaderError("cannot compile shader " + name + ":\n" + log);
  }
  return shader;
}

}  // namespace

std::vector<std::filesystem::path> shader_dir_candidates() { return resource_dir_candidates(kShaderFolder); }

std::filesystem::path find_shader_dir() {
  try {
    return find_resource_dir(kShaderFolder);
  } catch (const ResourceNotFound& e) {
    throw ShaderError(e.what());
  }
}

Program::~Program() {
  if (id_ != 0) glDeleteProgram(id_);
}

Program::Program(Program&& other) noexcept : id_(std::exchange(other.id_, 0)) {}

Program& Program::operator=(Program&& other) noexcept {
  if (this != &other) {
    if (id_ != 0) glDeleteProgram(id_);
    id_ = std::exchange(other.id_, 0);
  }
  return *this;
}

Program Program::from_files(const std::filesystem::path& vertex, const std::filesystem::path& fragment) {
  const std::string vertex_source = read_text(vertex);
  const std::string fragment_source = read_text(fragment);
  return from_sources(vertex_source, vertex.string(), fragment_source, fragment.string());
}

Program Program::from_sources(const std::string& vertex_source, const std::string& vertex_name,
                              const std::string& fragment_source, const std::string& fragment_name) {
  const GLuint vertex = compile(GL_VERTEX_SHADER, vertex_source, vertex_name);
  GLuint fragment = 0;
  try {
    fragment = compile(GL_FRAGMENT_SHADER, fragment_source, fragment_name);
  } catch (...) {
    glDeleteShader(vertex);
    throw;
  }
  const GLuint program = glCreateProgram();
  glAttachShader(program, vertex);
  glAttachShader(program, fragment);
  glLinkProgram(program);
  glDetachShader(program, vertex);
  glDetachShader(program, fragment);
  glDeleteShader(vertex);
  glDeleteShader(fragment);
  GLint ok = GL_FALSE;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (ok != GL_TRUE) {
    const std::string log = program_log(program);
    glDeleteProgram(program);
    throw ShaderError("cannot link shader program " + vertex_name + " + " + fragment_name + ":\n" + log);
  }
  return Program(program);
}

void Program::use() const { glUseProgram(id_); }

GLint Program::uniform(const char* name) const { return glGetUniformLocation(id_, name); }

Program load_program(const std::filesystem::path& dir, const std::string& name) {
  return Program::from_files(dir / (name + ".vert"), dir / (name + ".frag"));
}

}  // namespace nirslam::ui::gl
