#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "commands/subcommand.hpp"
#include "nirslam/session/session_export.hpp"

namespace nirslam::app {
namespace {

struct ExportCommandOptions {
  std::filesystem::path session;
  std::filesystem::path out;
  bool archive = false;
};

int export_to_folder(const ExportCommandOptions& options) {
  ExportOptions export_options;
  export_options.archive = options.archive;
  const ExportSummary summary = export_session(options.session, options.out, export_options);
  std::string files;
  for (const std::string& f : summary.files) files += (files.empty() ? "" : ", ") + f;
  std::printf("Exported %lld frames to %s: %s\n", static_cast<long long>(summary.frames),
              summary.folder.string().c_str(), files.c_str());
  if (!summary.evaluation.empty()) std::printf("%s\n", summary.evaluation.c_str());
  for (const std::string& note : summary.notes) std::printf("Not included: %s\n", note.c_str());
  std::printf("Report: %s\n", (summary.folder / "report.html").string().c_str());
  if (summary.archive) std::printf("Archive: %s\n", summary.archive->string().c_str());
  return 0;
}

}  // namespace

void add_export_command(CLI::App& parent, CommandAction& action) {
  auto options = std::make_shared<ExportCommandOptions>();
  CLI::App* cmd = parent.add_subcommand(
      "export", "Export a recorded session: a TUM monoVO dataset (images/, times.txt, camera.txt, pcalib.txt, "
                "vignette.png), trajectory, keyframes, points.ply, per-frame CSV and an HTML report with plots");
  cmd->add_option("session", options->session, "Recorded session folder")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("-o,--out", options->out, "Output folder (must not exist or be empty)")->required();
  cmd->add_flag("--archive", options->archive, "Also write everything into OUT.zip");
  cmd->callback([options, &action] { action = [options] { return export_to_folder(*options); }; });
}

}  // namespace nirslam::app
