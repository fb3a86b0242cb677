// I/O of haptic-topology. Offline tool code (allocates, throws).
#include "tools/topology/topology_io.hpp"

#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace haptic::tools::topology {

using nlohmann::json;

namespace {

json load_json(const std::string& path, const std::string& key) {
  std::ifstream f(path);
  if (!f) throw std::invalid_argument(key + ": cannot open '" + path + "'");
  try {
    return json::parse(f);
  } catch (const json::exception& e) {
    throw std::invalid_argument(key + ": '" + path + "' is not valid JSON: " + e.what());
  }
}

Eigen::MatrixXd json_matrix(const json& j, const std::string& key) {
  if (!j.is_array() || j.empty()) throw std::invalid_argument(key + ": expected an N x N array");
  const auto n = static_cast<Eigen::Index>(j.size());
  Eigen::MatrixXd m(n, n);
  for (Eigen::Index r = 0; r < n; ++r) {
    const json& row = j[static_cast<std::size_t>(r)];
    if (!row.is_array() || static_cast<Eigen::Index>(row.size()) != n) {
      throw std::invalid_argument(key + ": row " + std::to_string(r + 1) + " must have " + std::to_string(n) + " numbers");
    }
    for (Eigen::Index c = 0; c < n; ++c) {
      const json& v = row[static_cast<std::size_t>(c)];
      if (v.is_null()) {
        m(r, c) = std::numeric_limits<double>::infinity();
      } else if (v.is_number()) {
        m(r, c) = v.get<double>();
      } else {
        throw std::invalid_argument(key + ": entry (" + std::to_string(r + 1) + "," + std::to_string(c + 1) + ") is not a number");
      }
    }
  }
  return m;
}

}  // namespace

Eigen::MatrixXd read_delay_file(const std::string& path) {
  const json j = load_json(path, "--delays-file");
  if (j.is_object()) {
    if (!j.contains("mean_delay_ms")) throw std::invalid_argument("--delays-file: object needs key 'mean_delay_ms'");
    return json_matrix(j["mean_delay_ms"], "--delays-file mean_delay_ms");
  }
  return json_matrix(j, "--delays-file");
}

MeasuredLinks read_summary(const std::string& path, int users_hint) {
  const json j = load_json(path, "--from-summary");
  if (!j.is_object() || !j.contains("link_stats") || !j["link_stats"].is_array()) {
    throw std::invalid_argument("--from-summary: '" + path + "' has no list 'link_stats'");
  }
  const json& ls = j["link_stats"];
  int users = users_hint;
  for (const json& e : ls) {
    if (!e.is_object() || !e.contains("to") || !e.contains("from")) {
      throw std::invalid_argument("--from-summary: every link_stats entry needs 'to' and 'from'");
    }
    users = std::max({users, e["to"].get<int>(), e["from"].get<int>()});
  }
  if (users < 2) throw std::invalid_argument("--from-summary: link_stats names fewer than 2 users");
  const double inf = std::numeric_limits<double>::infinity();
  MeasuredLinks m;
  m.mean_delay_ms = Eigen::MatrixXd::Constant(users, users, inf);
  m.max_delay_ms = Eigen::MatrixXd::Constant(users, users, inf);
  m.loss_rate = Eigen::MatrixXd::Zero(users, users);
  for (int i = 0; i < users; ++i) m.mean_delay_ms(i, i) = m.max_delay_ms(i, i) = 0.0;
  for (const json& e : ls) {
    const int to = e["to"].get<int>(), from = e["from"].get<int>();
    if (to < 1 || from < 1 || to == from) {
      throw std::invalid_argument("--from-summary: link_stats to/from must be distinct users >= 1");
    }
    if (e.contains("delivered") && e["delivered"].is_number() && e["delivered"].get<double>() <= 0) {
      continue;  // nothing arrived on this link: no delay statistics (stays unavailable)
    }
    const double mean = e.value("mean_delay_ms", -1.0);
    const double mx = e.value("max_delay_ms", mean);
    const double loss = e.value("loss_rate", 0.0);
    if (!(mean >= 0) || !(mx >= mean) || !(loss >= 0 && loss < 1)) {
      throw std::invalid_argument("--from-summary: link " + std::to_string(to) + "<-" + std::to_string(from) +
                                  ": need mean_delay_ms >= 0, max_delay_ms >= mean, loss_rate in [0, 1)");
    }
    m.mean_delay_ms(to - 1, from - 1) = mean;
    m.max_delay_ms(to - 1, from - 1) = mx;
    m.loss_rate(to - 1, from - 1) = loss;
    ++m.entries;
  }
  return m;
}

Eigen::MatrixXd effective_mean_delay_ms(const MeasuredLinks& m, double period_s) {
  Eigen::MatrixXd d = m.mean_delay_ms;
  for (Eigen::Index i = 0; i < d.rows(); ++i) {
    for (Eigen::Index j = 0; j < d.cols(); ++j) {
      const double p = m.loss_rate(i, j);
      if (i != j && std::isfinite(d(i, j))) d(i, j) += period_s * 1e3 * p / (1.0 - p);
    }
  }
  return d;
}

GainFile read_gain_file(const std::string& path, int users) {
  const json j = load_json(path, "--gains-file");
  GainFile g;
  if (j.contains("blocks")) {
    g.dense = true;
    g.blocks.n = j.value("n", 0);
    if (g.blocks.n < 1) throw std::invalid_argument("--gains-file: 'n' must be >= 1 with 'blocks'");
    g.blocks.blocks.assign(static_cast<std::size_t>(users * users), Eigen::MatrixXd());
    for (auto it = j["blocks"].begin(); it != j["blocks"].end(); ++it) {
      int a = 0, b = 0;
      char dash = 0;
      std::istringstream ks(it.key());
      if (!(ks >> a >> dash >> b) || dash != '-' || a < 1 || b < 1 || a > users || b > users) {
        throw std::invalid_argument("--gains-file: block key '" + it.key() + "' is not 'i-j' with users 1.." + std::to_string(users));
      }
      const Eigen::MatrixXd blk = json_matrix(it.value(), "--gains-file blocks." + it.key());
      if (blk.rows() != g.blocks.n) throw std::invalid_argument("--gains-file: block " + it.key() + " must be n x n");
      g.blocks.blocks[static_cast<std::size_t>((a - 1) * users + (b - 1))] = blk;
    }
    return g;
  }
  auto mat = [&](const char* key) -> Eigen::MatrixXd {
    if (!j.contains(key)) throw std::invalid_argument(std::string("--gains-file: missing '") + key + "'");
    if (j[key].is_number()) return Eigen::MatrixXd::Constant(users, users, j[key].get<double>());
    Eigen::MatrixXd m = json_matrix(j[key], std::string("--gains-file ") + key);
    if (m.rows() != users) throw std::invalid_argument(std::string("--gains-file: '") + key + "' must be N x N, N = " + std::to_string(users));
    return m;
  };
  g.poly.a = mat("a");
  g.poly.b = mat("b");
  if (j.contains("mode_values")) {
    const auto v = j["mode_values"].get<std::vector<double>>();
    g.poly.mode_values = Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
  }
  return g;
}

}  // namespace haptic::tools::topology
