#include "platform/toml_config.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace haptic::platform::config {

std::string number_text(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

void bad(const std::string& key, const std::string& range) { throw std::invalid_argument("config: " + key + " must be " + range); }

toml::table parse_document(std::string_view toml_text) {
  try {
    return toml::parse(toml_text);
  } catch (const toml::parse_error& e) {
    std::ostringstream os;
    os << "config: TOML parse error: " << e.description() << " at line " << e.source().begin.line;
    throw std::invalid_argument(os.str());
  }
}

long long integer(View n, const std::string& key, long long def, long long lo, long long hi) {
  if (!n) return def;
  const auto v = n.value<long long>();
  if (!n.is_integer() || !v || *v < lo || *v > hi) bad(key, "an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  return *v;
}

double real(View n, const std::string& key, double def, double lo, double hi, const std::string& extra) {
  if (!n) return def;
  const auto v = n.value<double>();  // accepts integers too
  if (!v || !std::isfinite(*v) || *v < lo || *v > hi) bad(key, "a number in [" + number_text(lo) + ", " + number_text(hi) + "]" + extra);
  return *v;
}

std::string text(View n, const std::string& key, const std::string& def) {
  if (!n) return def;
  if (!n.is_string()) bad(key, "a string");
  return *n.value<std::string>();
}

bool boolean(View n, const std::string& key, bool def) {
  if (!n) return def;
  if (!n.is_boolean()) bad(key, "true or false");
  return *n.value<bool>();
}

void only_keys(View t, const std::string& where, std::initializer_list<const char*> known) {
  if (!t) return;
  if (!t.is_table()) bad("[" + where + "]", "a table");
  for (const auto& [k, v] : *t.as_table()) {
    (void)v;
    const std::string key(k.str());
    if (std::none_of(known.begin(), known.end(), [&](const char* s) { return key == s; })) {
      std::string list;
      for (const char* s : known) list += (list.empty() ? "" : ", ") + std::string(s);
      throw std::invalid_argument("config: unknown key " + (where.empty() ? key : where + "." + key) + " (known keys: " + list + ")");
    }
  }
}

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::invalid_argument("config: cannot open " + path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string path_beside(const std::string& path, const std::string& config_file) {
  const std::filesystem::path p(path);
  if (path.empty() || config_file.empty() || p.is_absolute()) return path;
  return (std::filesystem::path(config_file).parent_path() / p).string();
}

}  // namespace haptic::platform::config
