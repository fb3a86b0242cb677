#include "platform/option_spec.hpp"

#include <algorithm>
#include <cstring>
#include <sstream>
#include <stdexcept>

namespace haptic::platform::config {

namespace {

std::vector<std::string> split_choices(const char* choices) {
  std::vector<std::string> out;
  std::string cur;
  for (const char* c = choices; *c; ++c) {
    if (*c == '|') {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += *c;
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

bool has_special(const OptionDecl& d) { return !std::isnan(d.special); }

std::string interval(const OptionDecl& d) {
  const auto num = [&](double v) { return d.type == OptionType::kInteger ? std::to_string(static_cast<long long>(v)) : number_text(v); };
  std::string out(d.lo_open ? "(" : "[");
  return out.append(num(d.lo)).append(", ").append(num(d.hi)).append(d.hi_open ? ")" : "]");
}

bool in_range(const OptionDecl& d, double v) {
  if (has_special(d) && v == d.special) return true;
  const bool lo_ok = d.lo_open ? v > d.lo : v >= d.lo;
  const bool hi_ok = d.hi_open ? v < d.hi : v <= d.hi;
  return lo_ok && hi_ok;
}

}  // namespace

OptionDecl real_option(const char* section, const char* key, double def, double lo, double hi, const char* help) {
  OptionDecl d{section, key, OptionType::kReal};
  d.def = def;
  d.lo = lo;
  d.hi = hi;
  d.help = help;
  return d;
}
OptionDecl integer_option(const char* section, const char* key, double def, double lo, double hi, const char* help) {
  OptionDecl d = real_option(section, key, def, lo, hi, help);
  d.type = OptionType::kInteger;
  return d;
}
OptionDecl real3_option(const char* section, const char* key, double def, double lo, double hi, const char* help) {
  OptionDecl d = real_option(section, key, def, lo, hi, help);
  d.type = OptionType::kReal3;
  return d;
}
OptionDecl boolean_option(const char* section, const char* key, bool def, const char* help) {
  OptionDecl d{section, key, OptionType::kBoolean};
  d.def = def ? 1 : 0;
  d.help = help;
  return d;
}
OptionDecl text_option(const char* section, const char* key, const char* def, const char* help, const char* choices) {
  OptionDecl d{section, key, OptionType::kText};
  d.def_text = def;
  d.help = help;
  d.choices = choices;
  return d;
}

std::string option_key(const OptionDecl& d, const std::string& section_as_written) {
  const std::string s = section_as_written.empty() ? d.section : section_as_written;
  return s.empty() ? std::string(d.key) : s + "." + d.key;
}

std::string range_text(const OptionDecl& d) {
  const std::string special = has_special(d) ? number_text(d.special) + " or " : "";
  switch (d.type) {
    case OptionType::kInteger: return special + "an integer in " + interval(d) + d.note;
    case OptionType::kReal: return special + "a number in " + interval(d) + d.note;
    case OptionType::kReal3: return "an array of three numbers in " + interval(d) + d.note;
    case OptionType::kBoolean: return "true or false";
    case OptionType::kText: break;
  }
  const std::vector<std::string> c = split_choices(d.choices);
  if (c.empty()) return std::string("a string") + d.note;
  std::string out;
  for (std::size_t i = 0; i < c.size(); ++i) {
    if (i > 0) out.append(i + 1 == c.size() ? " or " : ", ");
    out.append(1, '"').append(c[i]).append(1, '"');
  }
  return out.append(d.note);
}

std::string default_text(const OptionDecl& d) {
  switch (d.type) {
    case OptionType::kInteger: return std::to_string(static_cast<long long>(d.def));
    case OptionType::kReal: return number_text(d.def);
    case OptionType::kReal3: {
      const std::string v = number_text(d.def);
      std::string out("[");
      return out.append(v).append(", ").append(v).append(", ").append(v).append("]");
    }
    case OptionType::kBoolean: return d.def != 0 ? "true" : "false";
    case OptionType::kText: break;
  }
  std::string out(1, '"');
  return out.append(d.def_text).append(1, '"');
}

namespace {

double checked_number(View n, const OptionDecl& d, const std::string& key) {
  const auto v = n.value<double>();  // accepts integers too
  if (!v || !std::isfinite(*v) || !in_range(d, *v)) bad(key, range_text(d));
  return *v;
}

}  // namespace

OptionValue read_option(View n, const OptionDecl& d, const std::string& key) {
  OptionValue v;
  v.given = static_cast<bool>(n);
  v.integer = static_cast<long long>(d.def);
  v.real = d.def;
  v.text = d.def_text;
  v.boolean = d.def != 0;
  std::fill(std::begin(v.real3), std::end(v.real3), d.def);
  if (!n) {
    if (d.required) bad(key, "present: " + range_text(d));
    return v;
  }
  switch (d.type) {
    case OptionType::kInteger:
      if (!n.is_integer()) bad(key, range_text(d));
      v.integer = *n.value<long long>();
      if (!in_range(d, static_cast<double>(v.integer))) bad(key, range_text(d));
      break;
    case OptionType::kReal: v.real = checked_number(n, d, key); break;
    case OptionType::kBoolean: v.boolean = boolean(n, key, false); break;
    case OptionType::kReal3:
      if (!n.is_array() || n.as_array()->size() != 3) bad(key, "an array of three numbers, e.g. [0.0, 0.0, 0.0]");
      for (std::size_t i = 0; i < 3; ++i) v.real3[i] = checked_number(n[i], d, key + "[" + std::to_string(i) + "]");
      break;
    case OptionType::kText: {
      v.text = text(n, key, "");
      const std::vector<std::string> c = split_choices(d.choices);
      if (!c.empty() && std::find(c.begin(), c.end(), v.text) == c.end()) bad(key + " = \"" + v.text + "\"", range_text(d));
      break;
    }
  }
  return v;
}

std::vector<std::string> section_keys(const std::vector<OptionDecl>& decls, const std::string& section, const std::vector<std::string>& extra) {
  std::vector<std::string> out;
  for (const OptionDecl& d : decls)
    if (section == d.section) out.emplace_back(d.key);
  out.insert(out.end(), extra.begin(), extra.end());
  return out;
}

void only_keys(View t, const std::string& where, const std::vector<std::string>& known) {
  if (!t) return;
  if (!t.is_table()) bad("[" + where + "]", "a table");
  for (const auto& [k, v] : *t.as_table()) {
    (void)v;
    const std::string key(k.str());
    if (std::find(known.begin(), known.end(), key) != known.end()) continue;
    std::string list;
    for (const std::string& s : known) list += (list.empty() ? "" : ", ") + s;
    throw std::invalid_argument("config: unknown key " + (where.empty() ? key : where + "." + key) + " (known keys: " + list + ")");
  }
}

namespace {
std::uint64_t fnv(std::uint64_t h, const void* data, std::size_t n) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ULL;
  return h;
}
}  // namespace

std::uint64_t hash_option(std::uint64_t h, const OptionDecl& d, const OptionValue& v) {
  h = fnv(h, d.section, std::strlen(d.section) + 1);
  h = fnv(h, d.key, std::strlen(d.key) + 1);
  switch (d.type) {
    case OptionType::kInteger: return fnv(h, &v.integer, sizeof v.integer);
    case OptionType::kReal: return fnv(h, &v.real, sizeof v.real);
    case OptionType::kReal3: return fnv(h, v.real3, sizeof v.real3);
    case OptionType::kBoolean: {
      const unsigned char b = v.boolean ? 1 : 0;
      return fnv(h, &b, 1);
    }
    case OptionType::kText: break;
  }
  return fnv(h, v.text.data(), v.text.size());
}

std::string markdown_table(const std::vector<OptionDecl>& decls) {
  static const char* kTypes[] = {"integer", "number", "string", "boolean", "3 numbers"};
  std::ostringstream os;
  os << "| key | type | accepted | default | description |\n|---|---|---|---|---|\n";
  for (const OptionDecl& d : decls) {
    std::string help = d.help;
    std::replace(help.begin(), help.end(), '|', '/');
    std::string range = range_text(d);
    std::replace(range.begin(), range.end(), '|', '/');
    os << "| `" << option_key(d) << "` | " << kTypes[static_cast<int>(d.type)] << " | " << range << " | "
       << (d.required ? std::string("required") : std::string("`").append(default_text(d)).append("`")) << " | " << help << (d.shared ? " (same on all stations)" : "") << " |\n";
  }
  return os.str();
}

}  // namespace haptic::platform::config
