#include "app/commands.h"
#include "fibres/architecture.h"
#include "morph/attachments.h"

#include <algorithm>

namespace fascicle::app {

namespace {
bool all_options = false;
}

bool show_all_options() { return all_options; }
void set_show_all_options(bool all) { all_options = all; }

void group_options(CLI::App* cmd, const std::vector<std::pair<std::string, std::vector<std::string>>>& groups,
                   const std::string& advanced) {
  for (CLI::Option* option : cmd->get_options()) {
    if (option->get_name() == "-h,--help" || option->get_name() == "--help") continue;
    std::string name = option->get_positional() ? option->get_name() : option->get_name();
    if (!option->get_lnames().empty()) name = "--" + option->get_lnames().front();
    std::string group = all_options ? advanced : "";
    for (const auto& [title, names] : groups)
      if (std::find(names.begin(), names.end(), name) != names.end()) {
        group = title;
        break;
      }
    option->group(group);
  }
}

void add_automatic_area_options(CLI::App* cmd, AttachmentOptions& options) {
  cmd->add_option("--end-fraction", options.end_fraction, "Automatic areas: share of the length taken at each end")
      ->capture_default_str();
  cmd->add_option("--connected-ends", options.connected_ends,
                  "Automatic areas: widen an end whose band is several pieces of surface (two heads) until it is "
                  "one piece")
      ->capture_default_str();
  cmd->add_option("--connect-margin", options.connect_margin,
                  "Automatic areas: share of the length added to a band widened by --connected-ends")
      ->capture_default_str();
  cmd->add_option("--max-end-fraction", options.max_end_fraction,
                  "Automatic areas: widest band --connected-ends may take, as a share of the length")
      ->capture_default_str();
}

void add_architecture_options(CLI::App* cmd, ArchitectureOptions& options) {
  cmd->add_option_function<std::string>(
         "--length-unit",
         [&options](const std::string& unit) {
           options.metres_per_unit = unit == "m" ? 1.0 : unit == "cm" ? 0.01 : 0.001;
         },
         "Unit of the mesh's coordinates for the architecture figures: mm (default), cm or m")
      ->check(CLI::IsMember({"mm", "cm", "m"}));
  cmd->add_option_function<double>(
      "--specific-tension", [&options](double n_per_cm2) { options.specific_tension = n_per_cm2 * 1e4; },
      "Specific tension for the maximum isometric force, N/cm^2 (default 61, Arnold et al. 2010)");
}

}  // namespace fascicle::app
