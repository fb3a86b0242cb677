#pragma once
// Reading a TOML configuration (toml++), one implementation for every section parser (the
// station file in firmware/, the [net] section in net/). Start-up only (allocates; not RT-safe).
// Every error throws std::invalid_argument "config: KEY must be RANGE", naming the key as it
// is written in the file.
#include <toml++/toml.h>

#include <initializer_list>
#include <string>
#include <string_view>

namespace haptic::platform::config {

using View = toml::node_view<const toml::node>;

[[noreturn]] void bad(const std::string& key, const std::string& range);
// A number as error messages print it (ostream default: 6 significant digits).
std::string number_text(double v);
// The document, or "config: TOML parse error: ... at line L".
toml::table parse_document(std::string_view toml_text);
// Absent: def. Present: must be of the type and within [lo, hi] (extra: appended to the range text).
long long integer(View n, const std::string& key, long long def, long long lo, long long hi);
double real(View n, const std::string& key, double def, double lo, double hi, const std::string& extra = "");
std::string text(View n, const std::string& key, const std::string& def);
bool boolean(View n, const std::string& key, bool def);
// Rejects a key of table `t` that is not in `known`, naming it and listing the known ones.
void only_keys(View t, const std::string& where, std::initializer_list<const char*> known);
// The whole file as text ("config: cannot open PATH").
std::string read_file(const std::string& path);
// A path a configuration file names, as the program opens it: a relative one is taken relative
// to the folder of the file that names it (config_file: its path as opened; "": not from a file,
// the path is left as it is).
std::string path_beside(const std::string& path, const std::string& config_file);

}  // namespace haptic::platform::config
