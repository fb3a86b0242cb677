#pragma once
// The [net] section's options, each declared once (net/options.cpp): key, type, range, default and
// help (platform/option_spec.hpp). parse_net_config reads its values by these declarations, the
// station file accepts exactly these keys, and `haptic-station options --markdown` documents them.
// Sections: "net", "net.impairment", "net.peers[]" (one entry of the peers array). Start-up only.
#include <vector>

#include "platform/option_spec.hpp"

namespace haptic::net {

const std::vector<platform::config::OptionDecl>& net_options();
// The declaration of `section`.`key` (throws std::logic_error for an undeclared one: a programming error).
const platform::config::OptionDecl& net_option(const char* section, const char* key);

}  // namespace haptic::net
