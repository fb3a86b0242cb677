// End-to-end session with a stand-in Novint Falcon: the Falcon stand-in
// (falcon_standin.hpp, a hand-made usbdevfs emulation, NOT a recording) is attached in this
// process; a two-station loopback lab (haptic-lab, a child process tree that inherits
// LD_PRELOAD=libumockdev-preload.so.0 and this testbed's UMOCKDEV_DIR) runs station 1 with
// device.kind = "falcon" through our libusb driver and station 2 with a simulated user. Checks:
// every station exits 0, station 1 ran the Falcon (firmware loaded byte for byte, homed, no
// fault, not a simulated user), the servo exchange ran (packets, nonzero motor commands), and the
// last packet the stand-in received commands zero (stop leaves the device safe).
// The stand-in answers through umockdev's socket to this process, a few hundred exchanges per
// second instead of a Falcon's 1000 (measured and printed), so station 1 allows 250 stale reads
// (device.max_stale_reads; default 5): an artefact of the emulation, not of the driver.
// Before the lab: `haptic-devices diag --kind falcon` against the same stand-in (exit 0, servo rate).
// Usage: falcon_station_session BUILD_BIN_DIR WORK_DIR   (exit 0 ok, 1 failed)
//        falcon_station_session --run 'COMMAND' WORK_DIR: instead of diag and the two-station lab, runs
//        COMMAND (sh -c, with $FALCON_FIRMWARE = the stand-in's firmware file) under the same stand-in, then
//        checks the Falcon side the same way (tests/firmware/station/documented_lab_check.sh: the shipped lab files).
#include "tests/drivers/falcon_standin.hpp"
#include "tests/support/file_text.hpp"

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>

namespace {
using haptic::test::file_text;

bool contains(const std::string& text, const std::string& what, const char* where, int& fails) {
  if (text.find(what) != std::string::npos) return true;
  std::printf("FAIL: %s does not contain %s\n", where, what.c_str());
  ++fails;
  return false;
}

void write_lab(const std::string& path, const std::string& firmware) {
  std::ofstream(path) << "[lab]\nusers = 2\nscenario = \"paper-best\"\nduration_s = 2.0\npush_end_s = 0.8\nrelease_s = 1.2\n"
                         "probe_s = 1.0\nstart_delay_s = 0.5\ndefault_host = \"127.0.0.1\"\n[network]\ntransport = \"udp\"\n"
                         "[topology]\nlinks = \"1-2\"\n[station]\nloss_allowance_ticks = 1\n[[stations]]\nid = 1\nhost = \"127.0.0.1\"\n"
                         "device = { kind = \"falcon\", falcon_firmware_path = \""
                      << firmware << "\", damping_Ns_per_m = 5.0, falcon_homing_timeout_s = 10.0, max_stale_reads = 250 }\n"
                      << "[[stations]]\nid = 2\nhost = \"127.0.0.1\"\ndevice = \"simulated\"\n";
}
// What the stand-in Falcon saw: firmware byte for byte, homing, servo packets with motor commands,
// and a last packet commanding zero (stop is safe). Prints one summary line; returns the failures.
int falcon_side_fails(haptic::testing::FalconBed& bed) {
  int fails = 0;
  std::lock_guard<std::mutex> l(bed.dev.mu);
  if (bed.dev.firmware != bed.firmware) std::printf("FAIL: the firmware did not arrive byte for byte\n"), ++fails;
  if (bed.dev.homing_packets < bed.dev.homing_packets_needed) std::printf("FAIL: no homing\n"), ++fails;
  if (bed.dev.plain_packets < 200) std::printf("FAIL: only %d servo packets after homing\n", bed.dev.plain_packets), ++fails;
  if (bed.dev.max_abs_motor == 0) std::printf("FAIL: the station never commanded a motor\n"), ++fails;
  if (bed.dev.last_motor[0] != 0 || bed.dev.last_motor[1] != 0 || bed.dev.last_motor[2] != 0)
    std::printf("FAIL: the last packet commands %d %d %d, not zero\n", bed.dev.last_motor[0], bed.dev.last_motor[1], bed.dev.last_motor[2]), ++fails;
  std::printf("falcon session: %d homing packets, %d servo packets, largest |motor command| %d, firmware %zu bytes; %s\n",
              bed.dev.homing_packets, bed.dev.plain_packets, bed.dev.max_abs_motor, bed.dev.firmware.size(), fails ? "FAILED" : "ok");
  return fails;
}
}  // namespace

int main(int argc, char** argv) {
  const bool run_mode = argc == 4 && std::string(argv[1]) == "--run";
  if (argc != 3 && !run_mode) {
    std::fprintf(stderr, "usage: falcon_station_session BUILD_BIN_DIR WORK_DIR | --run COMMAND WORK_DIR\n");
    return 2;
  }
  const std::string bin = run_mode ? "" : argv[1], work = run_mode ? argv[3] : argv[2];
  // Unbuffered: ctest reads a pipe, and a crash (the stand-in runs threads under LD_PRELOAD) would
  // otherwise lose everything printed so far; this test once failed under load with no output.
  std::setvbuf(stdout, nullptr, _IONBF, 0);
  std::cout << std::unitbuf;
  try {
    haptic::testing::FalconBed bed;
    if (std::system(("rm -rf '" + work + "' && mkdir -p '" + work + "'").c_str()) != 0) return 1;
    if (run_mode) {
      setenv("FALCON_FIRMWARE", bed.firmware_path.c_str(), 1);
      const int rc = std::system(argv[2]);
      int fails = rc != 0 ? 1 : 0;
      if (rc != 0) std::printf("FAIL: the command exited %d\n", rc);
      return fails + falcon_side_fails(bed) ? 1 : 0;
    }
    // Diagnostics mode first (the deploy guide's check before a session): exit 0, servo rate measured.
    const std::string diag = "'" + bin + "/haptic-devices' diag --kind falcon --falcon-firmware '" + bed.firmware_path +
                             "' --max-stale-reads 250 --force-N 0.3 --push-s 0.3 > '" + work + "/diag.log' 2>&1";
    const int diag_rc = std::system(diag.c_str());
    const std::string diag_out = file_text(work + "/diag.log");
    std::cout << diag_out;
    int diag_fails = 0;
    if (diag_rc != 0) std::printf("FAIL: haptic-devices diag --kind falcon exited %d\n", diag_rc), ++diag_fails;
    contains(diag_out, "servo frames of the device's own loop", "diag output", diag_fails);
    contains(diag_out, "force 0.3 N along x", "diag output", diag_fails);
    write_lab(work + "/lab.toml", bed.firmware_path);
    const std::string cmd = "'" + bin + "/haptic-lab' run '" + work + "/lab.toml' --runs-dir '" + work + "/runs' --no-plots > '" + work +
                            "/lab.log' 2>&1";
    const int rc = std::system(cmd.c_str());
    std::cout << file_text(work + "/lab.log");
    int fails = diag_fails;
    if (rc != 0) {
      std::printf("FAIL: haptic-lab run exited %d\n", rc);
      ++fails;
    }
    FILE* p = popen(("ls -d '" + work + "'/runs/*/ | head -1").c_str(), "r");
    char dir[4096] = {0};
    if (p == nullptr || std::fgets(dir, sizeof dir, p) == nullptr) {
      std::printf("FAIL: no run folder\n");
      return 1;
    }
    pclose(p);
    std::string run_dir(dir);
    run_dir.erase(run_dir.find_last_not_of("\n") + 1);
    const std::string st1 = file_text(run_dir + "station-1.json"), report = file_text(run_dir + "lab-report.json");
    contains(st1, "\"device\": \"Novint Falcon via libusb\"", "station-1.json", fails);
    contains(st1, "\"simulated_user\": false", "station-1.json", fails);
    contains(st1, "\"device_fault\": \"none\"", "station-1.json", fails);
    contains(st1, "\"kind\": \"falcon\"", "station-1.json", fails);
    contains(report, "\"exit_code\": 0", "lab-report.json", fails);
    fails += falcon_side_fails(bed);
    return fails ? 1 : 0;
  } catch (const std::exception& e) {
    std::printf("FAIL: %s\n", e.what());
    return 1;
  }
}
