#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "ui/gl/gl.hpp"

namespace nirslam::ui::gl {

// A shader that cannot be found, read, compiled or linked. The message names the file(s) and
// carries the GLSL compiler's or linker's log.
class ShaderError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

// The directories the shaders are looked for in, in order:
//   1. $NIRSLAM_SHADER_DIR (when set, it must exist: an explicit choice never falls through),
//   2. <directory of the executable>/../share/nirslam/shaders (installed),
//   3. the source tree's shaders/ (baked in at build time, so a build tree runs uninstalled).
std::vector<std::filesystem::path> shader_dir_candidates();

// The first existing directory of shader_dir_candidates(). Throws ShaderError listing every
// place it looked when none exists.
std::filesystem::path find_shader_dir();

// A linked GLSL program. Move-only; deletes the GL object (needs the context that created it).
class Program {
public:
  Program() = default;
  ~Program();
  Program(Program&& other) noexcept;
  Program& operator=(Program&& other) noexcept;
  Program(const Program&) = delete;
  Program& operator=(const Program&) = delete;

  // Reads, compiles and links a vertex and a fragment shader. Throws ShaderError naming the
  // missing file, or the file that failed to compile with the GLSL log.
  static Program from_files(const std::filesystem::path& vertex, const std::filesystem::path& fragment);

  // The same from text in memory; the names only appear in error messages.
  static Program from_sources(const std::string& vertex_source, const std::string& vertex_name,
                              const std::string& fragment_source, const std::string& fragment_name);

  GLuint id() const { return id_; }
  bool valid() const { return id_ != 0; }
  void use() const;
  // -1 when the program has no active uniform of that name (GL ignores writes to -1).
  GLint uniform(const char* name) const;

private:
  explicit Program(GLuint id) : id_(id) {}
  GLuint id_ = 0;
};

// Loads "<dir>/<name>.vert" and "<dir>/<name>.frag".
Program load_program(const std::filesystem::path& dir, const std::string& name);

}  // namespace nirslam::ui::gl
