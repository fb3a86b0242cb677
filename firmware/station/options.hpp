#pragma once
// The station file's options, each declared once (firmware/station/options.cpp: section, key, type,
// range, default, help, where the value goes). From that one table come: the TOML parser
// (parse_station_file), `haptic-station run`'s command-line overrides (--station.probe_s 2 ...),
// the plan fingerprint's hash of the options every station must share, and the documentation
// table (`haptic-station options --markdown`, committed as firmware/station/OPTIONS.md and checked
// by test_station). [net]'s keys are net/'s own table (net/options.hpp), in the same form.
// Adding an option is one row in kStationOptions (and the field it fills). Start-up only (not RT-safe).
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "platform/option_spec.hpp"

namespace haptic::firmware {

struct StationFile;

// One station-file option: its declaration and where its value goes.
struct StationOption {
  platform::config::OptionDecl decl;
  void (*set)(StationFile&, const platform::config::OptionValue&);
};

// The shipped options (every section but [net]).
const std::vector<StationOption>& station_options();
// Their declarations, then net/'s (the documentation table and the command line cover both).
std::vector<platform::config::OptionDecl> all_option_decls(const std::vector<StationOption>& station = station_options());

// Reads every option of `options` in the document into f (absent: the default), rejects keys a
// section does not declare, and sets f.shared_options_hash. Throws naming the key as written.
void read_station_options(const toml::table& doc, StationFile& f, const std::vector<StationOption>& options);

// KEY=VALUE overrides from the command line ("station.probe_s", "2"; "net.peer_silence_s", "0.5")
// written into the document text (the [network] alias when the file uses it): the value is read
// as a TOML value (2, 0.5, true, [0, 0, 1], "text") or else taken as a string, so the parser
// checks it and names the key. Throws naming a key no option declares.
std::string with_overrides(std::string_view toml_text, const std::vector<std::pair<std::string, std::string>>& sets,
                           const std::vector<platform::config::OptionDecl>& decls = all_option_decls());

// The documentation (Markdown) firmware/station/OPTIONS.md holds: every option of `decls`.
std::string options_markdown(const std::vector<platform::config::OptionDecl>& decls = all_option_decls());

}  // namespace haptic::firmware
