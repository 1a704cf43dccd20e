#pragma once
/// \file commands.h
/// Each `fascicle` subcommand registers itself on the CLI11 application. A command's callback
/// throws fascicle::Error on failure; main() turns that into a one-line message and exit code.

#include <CLI/CLI.hpp>

namespace fascicle {
struct AttachmentOptions;
}

namespace fascicle::app {

/// The automatic attachment areas' options (--end-fraction, --connected-ends, --connect-margin,
/// --max-end-fraction), one definition for decompose, check and sphere.
void add_automatic_area_options(CLI::App* cmd, AttachmentOptions& options);

void add_sample_command(CLI::App& app);   // fascicle sample
void add_repair_command(CLI::App& app);   // fascicle repair
void add_convert_command(CLI::App& app);  // fascicle convert
void add_bench_command(CLI::App& app);    // fascicle bench ...
void add_settle_command(CLI::App& app);   // fascicle settle
void add_sphere_command(CLI::App& app);   // fascicle sphere
void add_check_command(CLI::App& app);    // fascicle check
void add_decompose_command(CLI::App& app);  // fascicle decompose
void add_batch_command(CLI::App& app);    // fascicle batch
void add_render_command(CLI::App& app);   // fascicle render

}  // namespace fascicle::app
