#include <cstdio>
#include <exception>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "commands/app_config.hpp"
#include "commands/subcommand.hpp"
#include "nirslam/common/build_info.hpp"

int main(int argc, char** argv) {
  CLI::App cli{
      "nirslam: near-infrared visual SLAM for field rigs.\n"
      "Without a subcommand it opens the operator GUI on a simulated pipe tunnel\n"
      "(headless, writing a screenshot, when there is no display)."};
  cli.set_version_flag("--version", [] { return nirslam::version_text(); },
                       "Print the version and what it was built from (git commit, compiler, libraries) and exit");
  cli.require_subcommand(0, 1);
  bool verbose = false;
  cli.add_flag("-v,--verbose", verbose, "Print debug messages (also which shader and config folders are used)");
  std::string config_file;
  cli.add_option("--config", config_file, "Pipeline configuration (YAML); default: the shipped config/pipeline.yaml")
      ->check(CLI::ExistingFile);

  nirslam::app::CommandAction action;
  nirslam::app::add_gui_command(cli, action);
  nirslam::app::add_run_command(cli, action);
  nirslam::app::add_entropy_command(cli, action);
  nirslam::app::add_simulate_command(cli, action);
  nirslam::app::add_eval_command(cli, action);
  nirslam::app::add_advise_command(cli, action);
  nirslam::app::add_calibrate_sweep_command(cli, action);
  nirslam::app::add_calibrate_command(cli, action);
  nirslam::app::add_bench_command(cli, action);
  nirslam::app::add_devices_command(cli, action);
  nirslam::app::add_record_command(cli, action);
  nirslam::app::add_export_command(cli, action);
  nirslam::app::add_recover_command(cli, action);

  // Set after the subcommands: CLI11 copies the parent's footer into subcommands made after it.
  cli.footer(
      "Examples:\n"
      "  nirslam                                      the GUI on the simulated tunnel\n"
      "  nirslam gui /data/run42                      the GUI on a recorded TUM monoVO, EuRoC or image folder\n"
      "  nirslam simulate --scene parking --frames 200 -o parking\n"
      "                                               a simulated sequence with ground truth\n"
      "  nirslam run parking -o parking-run           trajectory, points, calibration, summary.json\n"
      "  nirslam eval parking-run/trajectory.txt parking/groundtruth.txt --plot error.png\n"
      "                                               accuracy against the ground truth\n"
      "  nirslam advise sweep-tunnel sweep-room       which illuminator power to use\n"
      "  nirslam gui sim:room --headless --screenshot room.png\n"
      "                                               render the GUI without a display\n"
      "Run 'nirslam SUBCOMMAND --help' for the options of one subcommand. Shaders and the default\n"
      "configuration are in /usr/share/nirslam (NIRSLAM_SHADER_DIR, NIRSLAM_CONFIG_DIR override them).");

  try {
    cli.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return cli.exit(e);
  }
  spdlog::set_level(verbose ? spdlog::level::debug : spdlog::level::info);

  try {
    nirslam::app::load_app_config(config_file);
    return action ? action() : nirslam::app::run_default_gui();
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}
