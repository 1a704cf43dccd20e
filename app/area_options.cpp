#include "app/commands.h"
#include "morph/attachments.h"

namespace fascicle::app {

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

}  // namespace fascicle::app
