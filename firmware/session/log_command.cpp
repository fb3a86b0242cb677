#include "firmware/session/log_command.hpp"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>

#include "firmware/session/log.hpp"
#include "platform/command_line.hpp"
#include "platform/install_paths.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace haptic::firmware {

namespace {

const char* const kBeforeUnits = "log written before haptic-station stored units on its datasets";

// An attribute read with `read` (h5::attr_str, attr_i64, attr_f64), or nothing when it is absent or
// of another type.
template <class T>
std::optional<T> opt_attr(hid_t obj, const std::string& name, T (*read)(hid_t, const std::string&)) {
  if (!h5::has_attr(obj, name)) return std::nullopt;
  try {
    return read(obj, name);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}
std::optional<std::string> opt_str(hid_t obj, const std::string& name) { return opt_attr(obj, name, h5::attr_str); }
std::optional<std::int64_t> opt_i64(hid_t obj, const std::string& name) { return opt_attr(obj, name, h5::attr_i64); }
std::optional<double> opt_f64(hid_t obj, const std::string& name) { return opt_attr(obj, name, h5::attr_f64); }

// Opens LOG, refusing what is not a session log with a message that says what it is instead.
h5::Id open_log(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw LogError(kLogExitBadInput, path + ": no such file");
  if (fs::is_directory(path, ec))
    throw LogError(kLogExitBadInput, path + ": is a directory, not a log (a run folder holds one station-<i>.h5 per station)");
  if (!h5::is_hdf5(path)) throw LogError(kLogExitBadInput, path + ": not an HDF5 file (a session log is station-<i>.h5, written by sim --record or [record])");
  h5::Id f;
  try {
    f = h5::open_file_read(path);
  } catch (const std::exception& e) {
    throw LogError(kLogExitBadInput, path + ": " + e.what());
  }
  if (opt_str(f.get(), "format").value_or("") != "haptic-session")
    throw LogError(kLogExitBadInput, path + ": an HDF5 file but not a haptic session log (no attribute format = \"haptic-session\")");
  if (!h5::exists(f.get(), kTicksGroup)) throw LogError(kLogExitBadInput, path + ": a session log without /ticks (damaged?)");
  return f;
}

// "m/s" -> "m_per_s", "N s/m" -> "Ns_per_m"; "1" and "" -> "" (no unit in a column name).
std::string unit_suffix(const std::string& units) {
  if (units.empty() || units == "1") return "";
  std::string s;
  for (char c : units) {
    if (c == ' ') continue;
    if (c == '/') s += "_per_";
    else s += c;
  }
  return s;
}

std::string join_unit(const std::string& base, const std::string& suffix) {
  if (suffix.empty()) return base;
  const std::string tail = "_" + suffix;
  if (base.size() > tail.size() && base.compare(base.size() - tail.size(), tail.size(), tail) == 0) return base;  // port_J, step_s
  return base + tail;
}

// One field of the log as the file has it.
struct FileField {
  std::string group, name;  // "ticks", "force"
  std::vector<std::uint64_t> shape;
  std::string dtype, units, description;  // units "" : not recorded
  bool units_recorded = false;
};

const LogField* program_field(const std::string& group, const std::string& name) {
  const auto find = [&](const auto& table) -> const LogField* {
    for (const auto& f : table)
      if (name == f.name) return &f;
    return nullptr;
  };
  return group == kTicksGroup ? find(kTickFields) : group == kPacketsGroup ? find(kPacketFields) : nullptr;
}

FileField file_field(hid_t file, const std::string& group, const std::string& name) {
  FileField f;
  f.group = group, f.name = name;
  const std::string path = group + "/" + name;
  f.shape = h5::shape(file, path);
  f.dtype = h5::dtype_name(file, path);
  h5::Id ds = h5::open_dataset(file, path);
  if (auto u = opt_str(ds.get(), kUnitsAttr)) f.units = *u, f.units_recorded = true;
  if (auto d = opt_str(ds.get(), kDescriptionAttr)) f.description = *d;
  if (!f.units_recorded)
    if (const LogField* p = program_field(group, name)) f.units = p->units, f.description = p->description;
  return f;
}

// The /ticks and /packets fields of the file, in the program's table order (then any others).
std::vector<FileField> row_fields(hid_t file) {
  std::vector<FileField> out;
  for (const std::string group : {kTicksGroup, kPacketsGroup}) {
    if (!h5::exists(file, group)) continue;
    h5::Id g = h5::open_group(file, group);
    std::vector<std::string> names = h5::dataset_paths(g.get());
    std::vector<std::string> ordered;
    const auto take = [&](const auto& table) {
      for (const auto& f : table)
        if (std::find(names.begin(), names.end(), f.name) != names.end()) ordered.push_back(f.name);
    };
    if (group == kTicksGroup) take(kTickFields);
    else take(kPacketFields);
    for (const auto& n : names)
      if (std::find(ordered.begin(), ordered.end(), n) == ordered.end()) ordered.push_back(n);
    for (const auto& n : ordered) out.push_back(file_field(file, group, n));
  }
  return out;
}

// The flag bits' names: the log's flag_bits attribute, else this program's rt::kTickFlagNames.
struct FlagName {
  std::string name, meaning;
};
std::map<int, FlagName> flag_names(hid_t file, bool& from_log) {
  std::map<int, FlagName> m;
  from_log = false;
  if (h5::exists(file, std::string(kTicksGroup) + "/flags")) {
    h5::Id ds = h5::open_dataset(file, std::string(kTicksGroup) + "/flags");
    if (auto text = opt_str(ds.get(), kFlagBitsAttr)) {
      std::istringstream in(*text);
      std::string line;
      while (std::getline(in, line)) {
        std::istringstream l(line);
        int bit = -1;
        std::string name, meaning;
        if (!(l >> bit >> name)) continue;
        std::getline(l >> std::ws, meaning);
        m[bit] = {name, meaning};
      }
      from_log = true;
      return m;
    }
  }
  for (const auto& f : rt::kTickFlagNames) m[std::countr_zero(f.bit)] = {f.name, f.meaning};
  return m;
}

std::string shape_text(const std::vector<std::uint64_t>& s) {
  std::string t = "(";
  for (std::size_t i = 0; i < s.size(); ++i) t += (i ? ", " : "") + std::to_string(s[i]);
  return t + (s.size() == 1 ? ",)" : ")");
}

std::string number(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

// The rows of a /ticks or /packets dataset in chronological order (a ring that wrapped is rotated
// by its group's ring_next_row).
std::uint64_t ring_next_row(hid_t file, const std::string& group) {
  h5::Id g = h5::open_group(file, group);
  const auto r = opt_i64(g.get(), "ring_next_row").value_or(0);
  return r > 0 ? static_cast<std::uint64_t>(r) : 0;
}

template <class T>
std::vector<T> read_column(hid_t file, const std::string& path, h5::Type type, std::uint64_t& cols, std::uint64_t rotate) {
  const auto s = h5::shape(file, path);
  cols = s.size() == 2 ? s[1] : 1;
  std::vector<T> v(s[0] * cols);
  h5::read_rows(file, path, type, v.data(), 0, s[0]);
  if (rotate > 0 && rotate < s[0]) std::rotate(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(rotate * cols), v.end());
  return v;
}

// One exported dataset: its values as text, row by row.
struct Column {
  std::vector<std::string> header;
  std::uint64_t rows = 0, cols = 1;
  std::vector<double> f;
  std::vector<std::int64_t> i;
  std::vector<std::uint64_t> u;
  std::string cell(std::uint64_t r, std::uint64_t c) const {
    const std::uint64_t at = r * cols + c;
    if (!f.empty()) return number(f[at]);
    if (!u.empty()) return std::to_string(u[at]);
    return std::to_string(i[at]);
  }
};

Column read_export_column(hid_t file, const FileField& ff, std::uint64_t rotate) {
  Column c;
  const std::string path = ff.group + "/" + ff.name;
  if (ff.dtype.rfind("float", 0) == 0) c.f = read_column<double>(file, path, h5::Type::kF64, c.cols, rotate);
  else if (ff.dtype == "uint64") c.u = read_column<std::uint64_t>(file, path, h5::Type::kU64, c.cols, rotate);
  else c.i = read_column<std::int64_t>(file, path, h5::Type::kI64, c.cols, rotate);
  c.rows = ff.shape.empty() ? 0 : ff.shape[0];
  const std::string suffix = unit_suffix(ff.units);
  if (ff.shape.size() == 1) c.header.push_back(join_unit(ff.name, suffix));
  else if (c.cols == 3) {
    for (const char* axis : {"x", "y", "z"}) c.header.push_back(join_unit(ff.name + "_" + axis, suffix));
  } else {
    for (std::uint64_t j = 0; j < c.cols; ++j) c.header.push_back(join_unit(ff.name + "_" + std::to_string(j), suffix));
  }
  return c;
}

}  // namespace

namespace {
// log_info's parts: the file's attributes and run length; every dataset; the flag bits' tick counts.
void info_header(hid_t f, std::ostream& out, const std::string& path) {
  const auto version = opt_i64(f, "version").value_or(0);
  out << path << ": haptic session log, version " << version << ", written by " << opt_str(f, "source").value_or("?");
  if (auto b = opt_str(f, "build_id"); b && !b->empty()) out << " (build " << b->substr(0, 12) << ")";
  out << "\n";
  std::string scenario = opt_str(f, "scenario").value_or("");
  if (scenario.empty()) {  // older logs: a simulator's fingerprint ends ", scenario NAME"
    const std::string fp = opt_str(f, "fingerprint").value_or(""), tag = ", scenario ";
    const auto at = fp.rfind(tag);
    scenario = at == std::string::npos ? "not recorded" : fp.substr(at + tag.size()) + " (from the fingerprint)";
  }
  out << "  station " << opt_i64(f, "station_id").value_or(0) << " of " << opt_i64(f, "users").value_or(0) << " users, scenario " << scenario << "\n";
  const double period = opt_f64(f, "period_s").value_or(0);
  out << "  scene " << opt_i64(f, "nodes").value_or(0) << " nodes, " << opt_i64(f, "dofs").value_or(0) << " dofs; period " << period * 1e3
      << " ms; packet values " << opt_str(f, "packet_values").value_or("?") << "\n";
  if (auto fp = opt_str(f, "fingerprint")) out << "  fingerprint: " << *fp << "\n";
  if (auto dmin = opt_f64(f, "damping_min_Ns_per_m"))
    out << "  passivity condition (eq. 18): " << (opt_i64(f, "passivity_condition_met").value_or(0) ? "met" : "NOT met") << ", B_i minimum " << *dmin
        << " N s/m\n";

  // Run length: the tick rows' run times.
  std::uint64_t cols = 0;
  const auto rot = ring_next_row(f, kTicksGroup);
  const auto k = read_column<std::int64_t>(f, std::string(kTicksGroup) + "/k", h5::Type::kI64, cols, rot);
  std::vector<double> steps;
  if (h5::exists(f, std::string(kTicksGroup) + "/step_s")) steps = read_column<double>(f, std::string(kTicksGroup) + "/step_s", h5::Type::kF64, cols, rot);
  const auto t = tick_end_times_s(k, steps, period);
  out << "  run: " << k.size() << " ticks";
  if (!k.empty()) out << " (k " << k.front() << " .. " << k.back() << ", run time " << (t.front() - (steps.empty() || steps.front() <= 0 ? period : steps.front()))
                      << " .. " << t.back() << " s)";
  const auto packets_written = opt_i64(f, "packets").value_or(0);
  const auto packet_rows = h5::exists(f, std::string(kPacketsGroup) + "/tick") ? static_cast<std::int64_t>(h5::shape(f, std::string(kPacketsGroup) + "/tick")[0]) : 0;
  out << ", " << packet_rows << " packets";
  if (packets_written != packet_rows) out << " (" << packets_written << " written)";
  const auto dropped = opt_i64(f, "dropped_records").value_or(0), trunc = opt_i64(f, "truncated_at_tick").value_or(-1);
  out << "; dropped records " << dropped << "; " << (trunc >= 0 ? "truncated at tick " + std::to_string(trunc) + " (size bound)" : "not truncated");
  const auto ring = opt_i64(f, "ring_ticks").value_or(0);
  out << "; " << (ring > 0 ? "ring of the last " + std::to_string(ring) + " ticks" + (opt_i64(f, "first_tick").value_or(0) > 0 ? " (wrapped)" : "") : "whole run")
      << "\n";
  if (auto err = opt_str(f, "writer_error"); err && !err->empty()) out << "  writer error: " << *err << "\n";
}

void info_datasets(hid_t f, std::ostream& out) {
  const bool units = h5::has_attr(f, kFieldUnitsAttr);
  if (!units) out << "  units not recorded (" << kBeforeUnits << "): the units below are this program's, for fields of the same name\n";

  out << "datasets (shape, dtype, units, description):\n";
  const auto paths = h5::dataset_paths(f);
  std::size_t width = 0;
  for (const auto& p : paths) width = std::max(width, p.size());
  for (const auto& p : paths) {
    const auto slash = p.find('/');
    FileField ff;
    const bool row_group = slash != std::string::npos && p.find('/', slash + 1) == std::string::npos &&
                           (p.compare(0, slash, kTicksGroup) == 0 || p.compare(0, slash, kPacketsGroup) == 0);
    if (row_group) {
      ff = file_field(f, p.substr(0, slash), p.substr(slash + 1));
    } else {
      ff.shape = h5::shape(f, p);
      ff.dtype = h5::dtype_name(f, p);
      h5::Id ds = h5::open_dataset(f, p);
      if (auto u = opt_str(ds.get(), kUnitsAttr)) ff.units = *u, ff.units_recorded = true;
      ff.description = opt_str(ds.get(), kDescriptionAttr).value_or("");
    }
    const std::string u = ff.units_recorded ? ff.units : ff.units.empty() ? "-" : ff.units + "?";
    out << "  " << std::left << std::setw(static_cast<int>(width)) << p << "  " << std::setw(12) << shape_text(ff.shape) << "  " << std::setw(7) << ff.dtype << "  "
        << std::setw(6) << u << "  " << ff.description << "\n" << std::right;
  }
  if (!units) out << "  (units marked ? are this program's: " << kBeforeUnits << ")\n";
}

void info_flags(hid_t f, std::ostream& out) {
  std::uint64_t cols = 0;
  // Flags: ticks each bit was set.
  if (h5::exists(f, std::string(kTicksGroup) + "/flags")) {
    const auto fl = read_column<std::int64_t>(f, std::string(kTicksGroup) + "/flags", h5::Type::kI64, cols, 0);
    std::uint64_t count[32] = {};
    std::uint64_t any = 0;
    for (auto v : fl) {
      if (v != 0) ++any;
      for (int b = 0; b < 32; ++b)
        if ((static_cast<std::uint64_t>(v) >> b) & 1u) ++count[b];
    }
    bool from_log = false;
    const auto names = flag_names(f, from_log);
    out << "flags (ticks with the bit set, of " << fl.size() << "; " << any << " ticks with any bit set; names "
        << (from_log ? "from the log's flag_bits" : std::string("not recorded in the log (") + kBeforeUnits + "): this program's rt::kTickFlagNames") << "):\n";
    for (const auto& [bit, n] : names)
      out << "  bit " << std::setw(2) << bit << "  " << std::left << std::setw(18) << n.name << std::right << std::setw(8) << (bit < 32 ? count[bit] : 0) << "  "
          << n.meaning << "\n";
    for (int b = 0; b < 32; ++b)
      if (count[b] > 0 && !names.count(b)) out << "  bit " << std::setw(2) << b << "  " << std::left << std::setw(18) << "(unnamed)" << std::right << std::setw(8) << count[b] << "\n";
  }
}

}  // namespace

void log_info(const std::string& path, std::ostream& out) {
  h5::Id file = open_log(path);
  const hid_t f = file.get();
  try {
    info_header(f, out, path);
    info_datasets(f, out);
    info_flags(f, out);
  } catch (const LogError&) {
    throw;
  } catch (const std::exception& e) {
    throw LogError(kLogExitFailed, path + ": damaged log: " + e.what());
  }
}

void log_export(const std::string& path, const std::vector<std::string>& requested, std::ostream& out) {
  h5::Id file = open_log(path);
  const hid_t f = file.get();
  std::vector<FileField> all;
  try {
    all = row_fields(f);
  } catch (const std::exception& e) {
    throw LogError(kLogExitFailed, path + ": damaged log: " + e.what());
  }
  std::vector<std::string> names;
  for (const auto& ff : all) names.push_back(ff.name);
  const auto list = [&] {
    std::string t;
    for (const auto& ff : all) t += (t.empty() ? "" : ", ") + ff.group + "/" + ff.name + (ff.units.empty() || ff.units == "1" ? "" : " [" + ff.units + "]");
    return t;
  };
  if (requested.empty()) throw LogError(kLogExitBadInput, "--field: name at least one field; this log's fields: " + list());
  std::vector<const FileField*> chosen;
  for (const auto& r : requested) {
    std::string name = r, group;
    if (const auto slash = r.find('/'); slash != std::string::npos) group = r.substr(0, slash), name = r.substr(slash + 1);
    const auto it = std::find_if(all.begin(), all.end(), [&](const FileField& ff) { return ff.name == name && (group.empty() || ff.group == group); });
    if (it == all.end()) {
      const std::string near = platform::nearest(name, names);
      throw LogError(kLogExitBadInput, "--field: no field '" + r + "' in " + path + (near.empty() ? "" : " (did you mean " + near + "?)") +
                                           "; its fields: " + list());
    }
    if (std::find(chosen.begin(), chosen.end(), &*it) == chosen.end()) chosen.push_back(&*it);
  }
  for (const auto* c : chosen)
    if (c->group != chosen.front()->group)
      throw LogError(kLogExitBadInput, "--field: " + chosen.front()->name + " is a /" + chosen.front()->group + " field and " + c->name + " a /" + c->group +
                                           " field: export them separately (one row per tick, one row per packet)");
  if (std::any_of(all.begin(), all.end(), [](const FileField& ff) { return !ff.units_recorded; }))
    std::cerr << "haptic-station log export: " << path << ": units not recorded (" << kBeforeUnits << "); the header's units are this program's\n";

  const std::string group = chosen.front()->group;
  std::vector<Column> cols;
  std::vector<std::string> head;
  std::vector<double> t;
  try {
    const auto rot = ring_next_row(f, group);
    if (group == kTicksGroup) {  // the run time of each tick row
      std::uint64_t c = 0;
      const auto k = read_column<std::int64_t>(f, group + "/k", h5::Type::kI64, c, rot);
      std::vector<double> steps;
      if (h5::exists(f, group + "/step_s")) steps = read_column<double>(f, group + "/step_s", h5::Type::kF64, c, rot);
      t = tick_end_times_s(k, steps, opt_f64(f, "period_s").value_or(0));
      head.push_back("t_s");
    }
    for (const auto* ff : chosen) {
      cols.push_back(read_export_column(f, *ff, rot));
      head.insert(head.end(), cols.back().header.begin(), cols.back().header.end());
    }
  } catch (const std::exception& e) {
    throw LogError(kLogExitFailed, path + ": damaged log: " + e.what());
  }
  std::uint64_t rows = cols.front().rows;
  for (const auto& c : cols) rows = std::min(rows, c.rows);
  for (std::size_t i = 0; i < head.size(); ++i) out << (i ? "," : "") << head[i];
  out << "\n";
  for (std::uint64_t r = 0; r < rows; ++r) {
    bool first = true;
    if (!t.empty()) out << number(t[r]), first = false;
    for (const auto& c : cols)
      for (std::uint64_t j = 0; j < c.cols; ++j) {
        if (!first) out << ",";
        out << c.cell(r, j);
        first = false;
      }
    out << "\n";
  }
}

std::vector<std::string> plot_logs(const std::vector<std::string>& args) {
  std::vector<std::string> logs;
  for (const auto& a : args) {
    std::error_code ec;
    if (!fs::is_directory(a, ec)) {
      logs.push_back(a);
      continue;
    }
    std::vector<std::pair<long, std::string>> found;
    for (const auto& e : fs::directory_iterator(a, ec)) {
      const std::string n = e.path().filename().string();
      if (n.rfind("station-", 0) != 0 || e.path().extension() != ".h5") continue;
      const std::string id = n.substr(8, n.size() - 8 - 3);
      if (id.empty() || id.find_first_not_of("0123456789") != std::string::npos) continue;
      found.emplace_back(std::stol(id), e.path().string());
    }
    if (found.empty()) throw LogError(kLogExitBadInput, a + ": a directory without station-<i>.h5 logs (record with sim --record or [record])");
    std::sort(found.begin(), found.end());
    for (const auto& [i, p] : found) logs.push_back(p);
  }
  return logs;
}

namespace {

constexpr const char* kPython = "/usr/bin/python3";

// `log plot`: exports each log's fields to a CSV in a scratch folder and draws them with
// tools/plots/plot_log.py on one run-time axis. Returns the script's exit status.
int log_plot(const LogArgs& a) {
  if (a.out.empty()) throw LogError(kLogExitBadInput, "--out: name the PNG to write");
  const auto logs = plot_logs(a.logs);
  std::vector<std::string> args{kPython, platform::tools_dir() + "/plots/plot_log.py", "--out", a.out};
  {  // the fields' units, from the first log (all logs of a run have the same layout)
    h5::Id f = open_log(logs.front());
    const auto all = row_fields(f.get());
    for (const auto& r : a.fields) {
      const std::string name = r.rfind(std::string(kTicksGroup) + "/", 0) == 0 ? r.substr(std::string(kTicksGroup).size() + 1) : r;
      const auto it = std::find_if(all.begin(), all.end(), [&](const FileField& ff) { return ff.group == kTicksGroup && ff.name == name; });
      if (it == all.end()) continue;  // log_export below refuses it with "did you mean"
      args.insert(args.end(), {"--field", name, it->units});
    }
  }
  if (!fs::exists(args[1])) throw LogError(kLogExitFailed, "no plot: " + args[1] + " not found (set HAPTIC_TOOLS_DIR)");
  if (!fs::exists(kPython)) throw LogError(kLogExitFailed, std::string("no plot: ") + kPython + " is missing (apt-get install python3-matplotlib)");
  const fs::path scratch = fs::temp_directory_path() / ("haptic-log-plot-" + std::to_string(getpid()));
  fs::create_directories(scratch);
  struct Cleanup {
    fs::path p;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(p, ec);
    }
  } cleanup{scratch};
  for (std::size_t i = 0; i < logs.size(); ++i) {
    std::ostringstream csv;
    log_export(logs[i], a.fields, csv);
    h5::Id f = open_log(logs[i]);
    const std::string label = "station " + std::to_string(opt_i64(f.get(), "station_id").value_or(static_cast<std::int64_t>(i + 1)));
    const std::string path = (scratch / ("log-" + std::to_string(i) + ".csv")).string();
    std::ofstream(path) << csv.str();
    args.push_back(label + "=" + path);
  }
  std::vector<char*> argv;
  for (auto& x : args) argv.push_back(x.data());
  argv.push_back(nullptr);
  std::fflush(nullptr);
  pid_t pid = -1;
  if (posix_spawn(&pid, kPython, nullptr, nullptr, argv.data(), environ) != 0) throw LogError(kLogExitFailed, std::string("no plot: cannot start ") + kPython);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) throw LogError(kLogExitFailed, "no plot: plot_log.py failed");
  return 0;
}

}  // namespace

LogCommands add_log_options(CLI::App& app, LogArgs& a) {
  LogCommands c;
  c.log = app.add_subcommand("log", "What a session log holds (info), its fields as CSV with units (export), a run's stations on one time axis (plot)");
  c.log->require_subcommand(1);
  const std::string status =
      "Exit status: 0 done; 2 bad options (an unknown --field names the nearest and lists the log's fields) or LOG is not a session log "
      "(no such file, a directory, not HDF5, no format = \"haptic-session\"); 3 the log is damaged (a dataset cannot be read), --out cannot be written or the plot cannot be drawn (/usr/bin/python3 with matplotlib).";
  c.log->footer(status);
  c.info = c.log->add_subcommand("info", "Print what LOG holds: station, scenario, run length, ticks, packets, every dataset (shape, dtype, units, "
                                         "description) and the flag bits decoded with the ticks each was set");
  c.info->add_option("log", a.log, "Session log (station-<i>.h5)")->required();
  c.info->footer(status);
  c.exp = c.log->add_subcommand("export", "Write /ticks (or /packets) fields of LOG as CSV: a header naming each column with its unit "
                                          "(t_s, force_x_N, ..., q_x_m, port_J; x_<dof>_m for a packet's dofs), rows in run order");
  c.exp->add_option("log", a.log, "Session log (station-<i>.h5)")->required();
  const auto names = [](const auto& table) {
    std::string t;
    for (const auto& f : table) t += (t.empty() ? "" : ", ") + std::string(f.name);
    return t;
  };
  c.exp->add_option("--field", a.fields, "Field(s) to write, NAME[,NAME...] (" + names(kTickFields) + "; or /packets fields: " + names(kPacketFields) +
                                             "; GROUP/NAME also accepted). /ticks rows start with t_s, the run time at the end of the tick "
                                             "(k_0 T plus the recorded steps T_k)")
      ->required()
      ->delimiter(',');
  c.exp->add_option("--out", a.out, "CSV file to write (default: standard output)");
  c.exp->footer(status);
  c.plot = c.log->add_subcommand("plot", "Draw /ticks fields of one or more logs on one run-time axis (PNG): a run folder's station-<i>.h5 "
                                         "together, one colour per station, one panel per field (tools/plots/plot_log.py, matplotlib); "
                                         "the recorded rows, nothing re-run");
  c.plot->add_option("logs", a.logs, "Session logs (station-<i>.h5) and/or run folders (all their station-<i>.h5)")->required();
  c.plot->add_option("--field", a.fields, "/ticks field(s) to draw, NAME[,NAME...] (" + names(kTickFields) + ")")->required()->delimiter(',');
  c.plot->add_option("--out", a.out, "PNG file to write")->required();
  c.plot->footer(status);
  return c;
}

int log_command(const LogCommands& c, const LogArgs& a) {
  const std::string who = std::string("haptic-station log ") + (c.info->parsed() ? "info" : c.plot->parsed() ? "plot" : "export");
  try {
    if (c.plot->parsed()) return log_plot(a);
    if (c.info->parsed()) {
      log_info(a.log, std::cout);
      return 0;
    }
    if (a.out.empty()) {
      log_export(a.log, a.fields, std::cout);
      return 0;
    }
    std::ostringstream csv;
    log_export(a.log, a.fields, csv);
    std::ofstream o(a.out, std::ios::binary | std::ios::trunc);
    if (!(o << csv.str()) || !o.flush()) throw LogError(kLogExitFailed, "--out " + a.out + ": cannot write");
    std::cerr << who << ": wrote " << a.out << "\n";
    return 0;
  } catch (const LogError& e) {
    std::cerr << who << ": error: " << e.what() << "\n";
    return e.status;
  }
}

}  // namespace haptic::firmware
