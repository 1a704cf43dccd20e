#pragma once
/// \file commands.h
/// Each `fascicle` subcommand registers itself on the CLI11 application. A command's callback
/// throws fascicle::Error on failure; main() turns that into a one-line message and exit code.

#include <CLI/CLI.hpp>

#include <string>
#include <utility>
#include <vector>

namespace fascicle {
struct AttachmentOptions;
struct ArchitectureOptions;
}  // namespace fascicle

namespace fascicle::app {

/// Whether the help shows every option (`--help-all`) or the main ones only (`--help`); set by
/// main() before the commands are added.
bool show_all_options();
void set_show_all_options(bool all);

/// Puts each option of `cmd` into the first group that lists its name (long name with the
/// dashes, or the positional's name); the others go to a group titled `advanced`, which the
/// help lists only with --help-all. Groups are shown in the order given.
void group_options(CLI::App* cmd, const std::vector<std::pair<std::string, std::vector<std::string>>>& groups,
                   const std::string& advanced);

/// The automatic attachment areas' options (--end-fraction, --connected-ends, --connect-margin,
/// --max-end-fraction), one definition for decompose, check and sphere.
void add_automatic_area_options(CLI::App* cmd, AttachmentOptions& options);

/// The architecture's options (--length-unit mm|cm|m, --specific-tension N/cm^2), one definition
/// for decompose and check; they write `options` when parsed.
void add_architecture_options(CLI::App* cmd, ArchitectureOptions& options);

void add_sample_command(CLI::App& app);     // fascicle sample
void add_repair_command(CLI::App& app);     // fascicle repair
void add_convert_command(CLI::App& app);    // fascicle convert
void add_bench_command(CLI::App& app);      // fascicle bench ...
void add_settle_command(CLI::App& app);     // fascicle settle
void add_sphere_command(CLI::App& app);     // fascicle sphere
void add_check_command(CLI::App& app);      // fascicle check
void add_decompose_command(CLI::App& app);  // fascicle decompose
void add_batch_command(CLI::App& app);      // fascicle batch
void add_render_command(CLI::App& app);     // fascicle render

}  // namespace fascicle::app
