#pragma once
// The command-line habits every CLI11 program of ours shares (header-only: include it only from a
// program that links CLI11::CLI11):
//   add_version_flag(app, "haptic-x")   --version prints platform::version_line (build id, git describe)
//   parse_command_line(app, argc, argv, usage_exit)
//                                       CLI11's parse; every usage error starts "haptic-x sub: error:";
//                                       an unknown option or subcommand is named with
//                                       "did you mean" the nearest one (also when CLI11 would first
//                                       have complained about a missing required option)
//   kNonNegativeInteger                 validator for unsigned options: "-1" is an error naming the
//                                       option, not 2^64 - 1
//   kNonNegative, kPositive             validators for numbers >= 0 and finite > 0 ("--x: Value -5 must be > 0")
// Start-up / non-RT only.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

#include "platform/version.hpp"

namespace haptic::platform {

// Levenshtein distance (insertions, deletions, substitutions), for "did you mean".
inline std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

// The candidate nearest to `word` if it is close (at most a third of its length, at least 2 edits,
// or `word` is a prefix of exactly that candidate), else "".
inline std::string nearest(const std::string& word, const std::vector<std::string>& candidates) {
  std::string best;
  std::size_t best_d = std::string::npos;
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(word, c);
    if (d < best_d) best_d = d, best = c;
  }
  if (best.empty()) return "";
  if (best_d <= std::max<std::size_t>(2, word.size() / 3)) return best;
  std::vector<std::string> prefixed;
  for (const auto& c : candidates)
    if (c.size() > word.size() && c.compare(0, word.size(), word) == 0) prefixed.push_back(c);
  return prefixed.size() == 1 ? prefixed.front() : "";
}

// --version: prints version_line(program) and exits 0.
inline void add_version_flag(CLI::App& app, const std::string& program) {
  app.set_version_flag("--version", version_line(program), "Print the version (project version, git describe, build id) and exit");
}

// The first argument of argv[1..] that `app` does not know, with its nearest known name: an option
// of the (sub)command it follows, or a subcommand where one is expected. When all are known,
// `argument` is empty and `where` names the last (sub)command given ("haptic-x sim").
struct UnknownArgument {
  std::string what, where, argument, suggestion;  // what: "option" or "subcommand"; where: "haptic-x sim"
};
inline UnknownArgument find_unknown_argument(CLI::App& app, int argc, char** argv) {
  CLI::App* cur = &app;
  std::string where = std::filesystem::path(app.get_name()).filename().string();  // CLI11 names it argv[0]
  std::size_t positionals_seen = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string tok = argv[i];
    if (tok == "--") break;
    const bool looks_numeric = tok.size() > 1 && tok[0] == '-' && (std::isdigit(static_cast<unsigned char>(tok[1])) || tok[1] == '.');
    if (tok.size() > 1 && tok[0] == '-' && !looks_numeric) {
      const std::string name = tok.substr(0, tok.find('='));
      const CLI::Option* opt = nullptr;
      for (CLI::App* a = cur; a != nullptr && opt == nullptr; a = a->get_parent()) {
        opt = a->get_option_no_throw(name);
        if (a != cur && opt != nullptr && !cur->get_fallthrough()) opt = nullptr;
      }
      if (opt == nullptr) {
        std::vector<std::string> names;
        for (const CLI::Option* o : cur->get_options()) {
          for (const auto& l : o->get_lnames()) names.push_back("--" + l);
          for (const auto& s : o->get_snames()) names.push_back("-" + s);
        }
        return {"option", where, name, nearest(name, names)};
      }
      // An option that takes a value consumes the next argument (unless written --opt=value).
      if (opt->get_type_size() != 0 && tok.find('=') == std::string::npos) ++i;
      continue;
    }
    // A positional word: a subcommand of `cur`, or one of its positional arguments.
    CLI::App* sub = nullptr;
    for (CLI::App* s : cur->get_subcommands({}))
      if (s->check_name(tok)) sub = s;
    if (sub != nullptr) {
      cur = sub;
      where += " " + tok;
      positionals_seen = 0;
      continue;
    }
    std::size_t positionals = 0;
    for (const CLI::Option* o : cur->get_options())
      if (o->get_positional()) ++positionals;
    if (positionals_seen < positionals) {
      ++positionals_seen;
      continue;
    }
    std::vector<std::string> subs;
    for (const CLI::App* s : cur->get_subcommands({})) subs.push_back(s->get_name());
    if (!subs.empty()) return {"subcommand", where, tok, nearest(tok, subs)};
    return {"argument", where, tok, ""};
  }
  return {"", where, "", ""};
}

// app.parse with our error messages. Returns -1 when the program should go on, else its exit
// status: 0 after --help/--version, `usage_exit` after a usage error (printed to stderr with
// "did you mean" for an unknown option or subcommand).
inline int parse_command_line(CLI::App& app, int argc, char** argv, int usage_exit) {
  try {
    app.parse(argc, argv);
    return -1;
  } catch (const CLI::Success& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    const UnknownArgument u = find_unknown_argument(app, argc, argv);
    if (!u.argument.empty()) {
      std::cerr << u.where << ": error: unknown " << u.what << " " << u.argument;
      if (!u.suggestion.empty()) std::cerr << " (did you mean " << u.suggestion << "?)";
      std::cerr << "\nRun with --help for more information.\n";
      return usage_exit;
    }
    std::cerr << u.where << ": error: " << e.what() << "\nRun with --help for more information.\n";
    return usage_exit;
  }
}

// Validator for an unsigned integer option: CLI11 would wrap "-1" to 2^64 - 1.
inline const CLI::Validator kNonNegativeInteger(
    [](std::string& s) {
      const auto first = s.find_first_not_of(" \t");
      if (first != std::string::npos && s[first] == '-') return "Value " + s + " must be >= 0";
      return std::string();
    },
    "UINT");

// A number >= 0 ("nan" refused). CLI11's NonNegativeNumber says "not in range 0 to 1.797...e308".
inline const CLI::Validator kNonNegative(
    [](std::string& s) {
      try {
        return std::stod(s) >= 0 ? std::string() : "Value " + s + " must be >= 0";
      } catch (const std::exception&) {
        return "Value " + s + " is not a number";
      }
    },
    "NONNEGATIVE");

// A finite number > 0 (durations, masses, counts that cannot be 0).
inline const CLI::Validator kPositive(
    [](std::string& s) {
      try {
        const double v = std::stod(s);
        return v > 0 && v <= std::numeric_limits<double>::max() ? std::string() : "Value " + s + " must be > 0";
      } catch (const std::exception&) {
        return "Value " + s + " is not a number";
      }
    },
    "POSITIVE");

}  // namespace haptic::platform
