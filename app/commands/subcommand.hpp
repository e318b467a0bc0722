#pragma once

#include <functional>

#include <CLI/CLI.hpp>

namespace nirslam::app {

// A subcommand registers its options on `parent` and, when the command line selects it, stores
// the work to do in `action`. main() runs the action after parsing; the exit code is its result.
using CommandAction = std::function<int()>;

void add_gui_command(CLI::App& parent, CommandAction& action);
void add_run_command(CLI::App& parent, CommandAction& action);
void add_entropy_command(CLI::App& parent, CommandAction& action);
void add_simulate_command(CLI::App& parent, CommandAction& action);
void add_eval_command(CLI::App& parent, CommandAction& action);
void add_advise_command(CLI::App& parent, CommandAction& action);
void add_calibrate_sweep_command(CLI::App& parent, CommandAction& action);
void add_calibrate_command(CLI::App& parent, CommandAction& action);
void add_bench_command(CLI::App& parent, CommandAction& action);
void add_devices_command(CLI::App& parent, CommandAction& action);
void add_record_command(CLI::App& parent, CommandAction& action);
void add_export_command(CLI::App& parent, CommandAction& action);
void add_recover_command(CLI::App& parent, CommandAction& action);

// What `nirslam` with no subcommand does: the GUI on the simulated tunnel, or the headless
// rendering of it when there is no display.
int run_default_gui();

}  // namespace nirslam::app
