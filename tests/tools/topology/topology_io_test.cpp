// haptic-topology input: measured link statistics (run/summary.json) and matrices.
#include <Eigen/Core>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <unistd.h>
#include <string>

#include "tools/topology/topology_io.hpp"

#include <CppUTest/TestHarness.h>

using namespace haptic::tools::topology;

namespace {
std::string write_temp(const std::string& text) {
  char name[] = "/tmp/topology_io_testXXXXXX";
  const int fd = mkstemp(name);
  if (fd >= 0) close(fd);
  std::ofstream(name) << text;
  return name;
}
}  // namespace

TEST_GROUP(TopologyIo){};

TEST(TopologyIo, SummaryLinkStatsFillRowReceiverColumnSender) {
  const std::string path = write_temp(R"({"link_stats": [
      {"to": 1, "from": 2, "mean_delay_ms": 4.5, "max_delay_ms": 6.0, "loss_rate": 0.05},
      {"to": 2, "from": 1, "mean_delay_ms": 8.0, "max_delay_ms": 12.0, "loss_rate": 0.0},
      {"to": 3, "from": 1, "mean_delay_ms": 3.0, "max_delay_ms": 5.0, "loss_rate": 0.5}]})");
  const MeasuredLinks m = read_summary(path, 0);
  std::remove(path.c_str());
  LONGS_EQUAL(3, m.mean_delay_ms.rows());
  LONGS_EQUAL(3, m.entries);
  DOUBLES_EQUAL(4.5, m.mean_delay_ms(0, 1), 0);
  DOUBLES_EQUAL(8.0, m.mean_delay_ms(1, 0), 0);
  DOUBLES_EQUAL(12.0, m.max_delay_ms(1, 0), 0);
  CHECK(std::isinf(m.mean_delay_ms(1, 2)));  // 2 <- 3 not measured: no link
  const Eigen::MatrixXd eff = effective_mean_delay_ms(m, 0.002);
  DOUBLES_EQUAL(4.5 + 2.0 * 0.05 / 0.95, eff(0, 1), 1e-12);  // sustained samples age by T p/(1-p)
  DOUBLES_EQUAL(3.0 + 2.0, eff(2, 0), 1e-12);
}

TEST(TopologyIo, SummaryWithoutLinkStatsNamesTheKey) {
  const std::string path = write_temp(R"({"runs": []})");
  try {
    read_summary(path, 0);
    std::remove(path.c_str());
    FAIL("expected std::invalid_argument");
  } catch (const std::invalid_argument& e) {
    std::remove(path.c_str());
    CHECK(std::string(e.what()).find("link_stats") != std::string::npos);
  }
}

TEST(TopologyIo, MatrixTextParsesRowsAndInf) {
  using haptic::model::parse_delay_matrix;  // the simulator's --delay-matrix parser
  const Eigen::MatrixXd m = parse_delay_matrix("0,4,inf; 8,0,80; 4,100,0", "--delays");
  LONGS_EQUAL(3, m.rows());
  DOUBLES_EQUAL(80.0, m(1, 2), 0);
  CHECK(std::isinf(m(0, 2)));
  CHECK_THROWS(std::invalid_argument, parse_delay_matrix("0,4;8", "--delays"));
  CHECK_THROWS(std::invalid_argument, parse_delay_matrix("0,x;8,0", "--delays"));
}
