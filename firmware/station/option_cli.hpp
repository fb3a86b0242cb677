#pragma once
// `haptic-station run`'s command-line overrides, produced from the option declarations
// (options.hpp): one `--SECTION.KEY VALUE` per declared option (not the per-peer keys), with its
// declared help, accepted values and default; each given one is collected as a KEY=VALUE pair
// for with_overrides, so the station file's parser checks it and names the key. Header-only:
// include it only from a program that links CLI11. Start-up only (not RT-safe).
#include <CLI/CLI.hpp>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "firmware/station/options.hpp"

namespace haptic::firmware {

inline void add_option_overrides(CLI::App* app, const std::vector<platform::config::OptionDecl>& decls,
                                 std::vector<std::pair<std::string, std::string>>& sets) {
  using platform::config::OptionType;
  for (const platform::config::OptionDecl& d : decls) {
    if (std::strchr(d.section, '[')) continue;  // net.peers[]: one per peer, in the file only
    const std::string key = platform::config::option_key(d);
    const char* type = d.type == OptionType::kInteger ? "INT" : d.type == OptionType::kReal ? "NUM" : d.type == OptionType::kBoolean ? "BOOL"
                       : d.type == OptionType::kReal3 ? "[X,Y,Z]" : "TEXT";
    app->add_option_function<std::string>("--" + key, [&sets, key](const std::string& v) { sets.emplace_back(key, v); },
                                          std::string(d.help) + " (" + platform::config::range_text(d) + "; default " +
                                              (d.required ? std::string("none: required") : platform::config::default_text(d)) + ")")
        ->type_name(type)
        ->group("Station file keys (each overrides the file's value; firmware/station/OPTIONS.md)");
  }
}

}  // namespace haptic::firmware
