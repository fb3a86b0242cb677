#pragma once
// One declaration per configuration option: section, key, type, range, default and help, from
// which a program's TOML section parser, its command-line overrides, its fingerprint of the
// options every station must share and its documentation table are all produced (firmware/station/
// options.hpp, net/options.hpp). Start-up only (allocates; not RT-safe). Errors are
// platform::config's: "config: KEY must be RANGE", the key named as written in the file.
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "platform/toml_config.hpp"

namespace haptic::platform::config {

enum class OptionType { kInteger, kReal, kText, kBoolean, kReal3 };

inline constexpr double kNoSpecial = std::numeric_limits<double>::quiet_NaN();

// One option as declared. Numbers: accepted in [lo, hi] (lo_open / hi_open: that bound excluded),
// and also `special` when it is not NaN (e.g. -1 = "from the measurement", 0 = "the scenario's").
// Text: `choices` "a|b|c" lists the accepted values ("" = any string). `note` is appended to the
// range in errors and to the help ("(0 = off)"). `shared`: every station of a session must use the
// same value (it feeds the plan fingerprint). `section` is the table as written in the docs
// ("station", "device", "net.impairment"); `key` the key within it.
struct OptionDecl {
  const char* section;
  const char* key;
  OptionType type;
  double lo = 0, hi = 0;
  double def = 0;               // numbers and booleans (0/1)
  const char* def_text = "";    // text
  const char* help = "";
  const char* choices = "";
  const char* note = "";
  double special = kNoSpecial;
  bool lo_open = false, hi_open = false;
  bool shared = false;
  bool required = false;

  OptionDecl with_special(double v) const { OptionDecl c = *this; c.special = v; return c; }
  OptionDecl with_note(const char* n) const { OptionDecl c = *this; c.note = n; return c; }
  OptionDecl open_low() const { OptionDecl c = *this; c.lo_open = true; return c; }
  OptionDecl open_high() const { OptionDecl c = *this; c.hi_open = true; return c; }
  OptionDecl same_on_all_stations() const { OptionDecl c = *this; c.shared = true; return c; }
  OptionDecl must_be_given() const { OptionDecl c = *this; c.required = true; return c; }
};

// Declarations by type (help: one line, the docs table's description).
OptionDecl real_option(const char* section, const char* key, double def, double lo, double hi, const char* help);
OptionDecl integer_option(const char* section, const char* key, double def, double lo, double hi, const char* help);
OptionDecl boolean_option(const char* section, const char* key, bool def, const char* help);
OptionDecl text_option(const char* section, const char* key, const char* def, const char* help, const char* choices = "");
OptionDecl real3_option(const char* section, const char* key, double def, double lo, double hi, const char* help);

// A value as read (absent: the declared default, given = false).
struct OptionValue {
  bool given = false;
  long long integer = 0;
  double real = 0;
  std::string text;
  bool boolean = false;
  double real3[3] = {0, 0, 0};
};

// "station.probe_s" (the key as written: `section_as_written` replaces the declared section, e.g.
// "network" for "net").
std::string option_key(const OptionDecl& d, const std::string& section_as_written = "");
// The accepted values as errors and docs print them: "a number in [0, 100)", "-1 or an integer in
// [0, 1000]", "\"udp\" or \"raw\"", "true or false".
std::string range_text(const OptionDecl& d);
// The default as the docs print it: 1.5, "udp", false, [0, 0, 0].
std::string default_text(const OptionDecl& d);
// Reads the option from its table (absent: the default); throws naming `key`.
OptionValue read_option(View table, const OptionDecl& d, const std::string& key);
// The keys of `section` among `decls`, for only_keys (extra: keys handled by hand, e.g. "peers").
std::vector<std::string> section_keys(const std::vector<OptionDecl>& decls, const std::string& section,
                                      const std::vector<std::string>& extra = {});
// Rejects a key of table `t` not in `known` (as only_keys).
void only_keys(View t, const std::string& where, const std::vector<std::string>& known);
// Mixes a value into a 64-bit FNV-1a hash (the shared options' fingerprint).
std::uint64_t hash_option(std::uint64_t h, const OptionDecl& d, const OptionValue& v);
// The documentation table (Markdown): | key | type | range | default | description |, one row per option.
std::string markdown_table(const std::vector<OptionDecl>& decls);

}  // namespace haptic::platform::config
