#include <cstdio>
#include <exception>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "commands/app_config.hpp"
#include "commands/subcommand.hpp"

int main(int argc, char** argv) {
  CLI::App cli{
      "nirslam: near-infrared visual SLAM for field rigs.\n"
      "Without a subcommand it opens the operator GUI on a simulated pipe tunnel\n"
      "(headless, writing a screenshot, when there is no display)."};
  cli.set_version_flag("--version", std::string("nirslam ") + NIRSLAM_VERSION);
  cli.require_subcommand(0, 1);
  bool verbose = false;
  cli.add_flag("-v,--verbose", verbose, "Print debug messages");
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
