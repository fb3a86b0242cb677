// Each station-file option is declared once (firmware/station/options.cpp, net/options.cpp): the
// parser, `run`'s command line, the fingerprint and the documentation table all come from it, and
// the documented keys are the accepted keys.
#include <CppUTest/TestHarness.h>

#include <CLI/CLI.hpp>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "firmware/scenario.hpp"
#include "firmware/station/config.hpp"
#include "firmware/station/option_cli.hpp"
#include "firmware/station/options.hpp"
#include "firmware/station/plan.hpp"
#include "net/wire.hpp"
#include "tests/firmware/station/station_files.hpp"

using namespace haptic;
using namespace haptic::firmware;
using platform::config::OptionDecl;

namespace {

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string hub_text(const std::string& station_extra = "") {
  test::StationText s;
  s.peers = {2, 3, 4};
  s.station_extra = station_extra;
  return s.text();
}

std::string error_of(const std::string& text, const std::vector<StationOption>& options = station_options()) {
  try {
    parse_station_file(text, options);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

// `run --help` with the overrides of `decls`, and the pairs a command line gives.
std::string run_help(const std::vector<OptionDecl>& decls) {
  CLI::App app;
  std::vector<std::pair<std::string, std::string>> sets;
  add_option_overrides(&app, decls, sets);
  return app.help();
}

double g_test_gain = -1;  // where the test-only option's value goes

}  // namespace

TEST_GROUP(StationOptions){};

// The acceptance of "adding an option is one edit": one declaration, and the parser reads it (range
// checked, key named), `run --help` lists it, the command line overrides it, the fingerprint
// changes with it and the documentation table shows it.
TEST(StationOptions, ANewOptionIsOneDeclarationInTheParserTheCommandLineTheFingerprintAndTheDocs) {
  std::vector<StationOption> opts = station_options();
  opts.push_back({platform::config::real_option("station", "test_gain", 0.5, 0, 2, "a test-only gain").open_high().same_on_all_stations(),
                  [](StationFile&, const platform::config::OptionValue& v) { g_test_gain = v.real; }});
  const std::vector<OptionDecl> decls = all_option_decls(opts);
  // the parser
  const StationFile with = parse_station_file(hub_text("test_gain = 1.5\n"), opts);
  DOUBLES_EQUAL(1.5, g_test_gain, 0);
  const StationFile without = parse_station_file(hub_text(), opts);
  DOUBLES_EQUAL(0.5, g_test_gain, 0);
  STRCMP_EQUAL("config: station.test_gain must be a number in [0, 2)", error_of(hub_text("test_gain = 2\n"), opts).c_str());
  CHECK(contains(error_of(hub_text("test_gain = 1.5\n")), "unknown key station.test_gain"));
  // the command line
  CHECK(contains(run_help(decls), "--station.test_gain NUM"));
  CHECK(contains(run_help(decls), "a test-only gain (a number in [0, 2); default 0.5)"));
  CHECK_FALSE(contains(run_help(all_option_decls()), "test_gain"));
  CLI::App app;
  std::vector<std::pair<std::string, std::string>> sets;
  add_option_overrides(&app, decls, sets);
  const char* argv[] = {"run", "--station.test_gain", "1.25"};
  app.parse(3, argv);
  parse_station_file(with_overrides(hub_text(), sets, decls), opts);
  DOUBLES_EQUAL(1.25, g_test_gain, 0);
  // the fingerprint
  const BuiltScenario built = build_scenario(make_scenario("paper-best"));
  STRCMP_EQUAL("gains or shared station options (hash) differs",
               net::fingerprint_difference(station_fingerprint(built, with), station_fingerprint(built, without)).c_str());
  STRCMP_EQUAL("", net::fingerprint_difference(station_fingerprint(built, without), station_fingerprint(built, parse_station_file(hub_text(), opts))).c_str());
  // the documentation table
  CHECK(contains(options_markdown(decls), "| `station.test_gain` | number | a number in [0, 2) | `0.5` | a test-only gain (same on all stations) |"));
}

// firmware/station/OPTIONS.md is the generated table (regenerate: haptic-station options --markdown > firmware/station/OPTIONS.md).
TEST(StationOptions, TheCommittedOptionsTableIsTheGeneratedOne) {
  const std::string committed = read_text(std::string(HAPTIC_SOURCE_DIR) + "/firmware/station/OPTIONS.md");
  if (committed != options_markdown())
    FAIL("firmware/station/OPTIONS.md differs from `haptic-station options --markdown`: regenerate it from the declarations");
}

// Every declared key, [net]'s included, is accepted by the station file's parser (a key refused as
// unknown would be documented and yet unusable, as net.peer_silence_s was).
TEST(StationOptions, EveryDeclaredKeyIsAccepted) {
  for (const OptionDecl& d : all_option_decls()) {
    const std::string section = d.section;
    if (section == "net.peers[]" || d.type == platform::config::OptionType::kReal3) continue;
    std::string value = platform::config::default_text(d);
    std::string t = hub_text();
    if (section == "net") t.insert(t.find("[[net.peers]]"), std::string(d.key) + " = " + value + "\n");
    else if (section == "net.impairment") t.insert(t.find("[[net.peers]]"), "[net.impairment]\n" + std::string(d.key) + " = " + value + "\n");
    else if (section == "station") t.insert(t.find("[device]"), std::string(d.key) + " = " + value + "\n");
    else t = "[" + section + "]\n" + d.key + " = " + value + "\n" + t;
    const std::string e = error_of(t);
    if (contains(e, "unknown key")) FAIL((platform::config::option_key(d) + ": " + e).c_str());
  }
  CHECK(contains(error_of(hub_text("no_such_key = 1\n")), "unknown key station.no_such_key"));
}

// The keys the READMEs name (`station.probe_s`, `net.peer_silence_s = 0.25`, `network.listen`) are
// declared keys. Not station-file keys: a lab file's `network.routed` (tools/lab/haptic-lab writes
// station.allow_routed_peers from it) and the table name `net.impairment`.
TEST(StationOptions, TheKeysTheDocsNameAreTheDeclaredKeys) {
  std::set<std::string> declared = {"net.routed", "net.impairment"};
  for (const OptionDecl& d : all_option_decls()) declared.insert(platform::config::option_key(d));
  const std::regex key("`((station|scene|device|rt|loop|gpio|telemetry|net|network)(\\.impairment)?\\.[a-z_0-9]+)( *=[^`]*)?`");
  int named = 0;
  for (const char* doc : {"README.md", "firmware/README.md", "net/README.md", "firmware/deploy/README.md", "tools/lab/README.md"}) {
    const std::string text = read_text(std::string(HAPTIC_SOURCE_DIR) + "/" + doc);
    CHECK(!text.empty());
    for (std::sregex_iterator m(text.begin(), text.end(), key), end; m != end; ++m) {
      std::string k = (*m)[1].str();
      if (k.rfind("network.", 0) == 0) k = "net." + k.substr(8);
      if (k == "net.listen") k = "net.bind";
      ++named;
      if (!declared.count(k)) FAIL((std::string(doc) + " names `" + (*m)[1].str() + "`, which no option declares").c_str());
    }
  }
  CHECK(named > 10);  // the pattern still finds keys (56 at the time of writing)
}

// One range, written once: the deadband's [0, 100) as the docs table says, and a value the
// parser takes for it; the command line checks through the same parser, naming the key.
TEST(StationOptions, ARangeIsWrittenOnceAndTheCommandLineIsCheckedByTheParser) {
  STRCMP_CONTAINS("| `station.tx_deadband_mm` | number | a number in [0, 100) |", options_markdown().c_str());
  STRCMP_EQUAL("config: station.tx_deadband_mm must be a number in [0, 100)", error_of(hub_text("tx_deadband_mm = 100\n")).c_str());
  CHECK(error_of(hub_text("tx_deadband_mm = 99.9999\n")).empty());
  STRCMP_EQUAL("config: station.probe_s must be a number in [0.2, 60]",
               error_of(with_overrides(hub_text(), {{"station.probe_s", "100"}})).c_str());
  STRCMP_EQUAL("config: station.pushes = \"bogus\" must be \"spread\" or \"asymmetric\"",
               error_of(with_overrides(hub_text(), {{"station.pushes", "bogus"}})).c_str());
  const StationFile f = parse_station_file(with_overrides(hub_text(), {{"net.peer_silence_s", "0.5"}, {"station.probe_s", "2"}}));
  DOUBLES_EQUAL(2.0, f.station.probe_s, 0);
  CHECK(contains(f.text, "peer_silence_s = 0.5"));
  try {
    with_overrides(hub_text(), {{"station.no_such_key", "1"}});
    FAIL("an undeclared key on the command line was accepted");
  } catch (const std::invalid_argument& e) {
    STRCMP_CONTAINS("unknown key station.no_such_key", e.what());
  }
}
