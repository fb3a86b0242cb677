#pragma once
// The live web view's server: HTTP + WebSocket through Debian's libwebsockets,
// on its own non-RT thread. Serves the page (tools/view/, found with platform::tools_dir()),
// three.js from Debian's libjs-three and Chart.js from libjs-chart.js (both local: no CDN), and a
// WebSocket protocol "haptic-view": one scene message per browser, then frames at rate_hz. It
// never touches the RT tick: frames come from a `FrameSource` called on the server thread (the
// station's reads a latest-value mailbox the tick fills). A browser that is not ready for a frame
// misses it (counted in frames_dropped). With ViewCallbacks::status, GET /status.json answers its
// JSON (no-store), also built on the server thread. Listens on 127.0.0.1 unless configured otherwise.
// Nothing here is RT-safe.
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>

namespace haptic::firmware {

struct ViewServerConfig {
  std::string bind = "127.0.0.1";  // interface address (station.view_bind)
  int port = 0;                    // station.view_port
  double rate_hz = 30;             // frames per second offered to browsers
  std::string assets_dir;          // "": platform::tools_dir() + "/view"
  std::string three_dir = "/usr/share/javascript/three";
  std::string chart_dir = "/usr/share/javascript/chart.js";
};

struct ViewCallbacks {
  std::function<std::string()> scene;                   // the scene message (JSON), once per browser
  std::function<bool(std::string& frame)> next_frame;   // a new frame (JSON) or false; rate_hz times per second
  std::function<void(const std::string& message)> on_message;  // a browser's message (e.g. the replay timeline), may be empty
  // GET /status.json (machine-readable state for haptic-lab's console), called on the server thread;
  // empty: no such path (404)
  std::function<std::string()> status;
};

struct ViewServerStats {
  std::uint64_t frames = 0;          // frames produced
  std::uint64_t frames_sent = 0;     // frame messages written to browsers
  std::uint64_t frames_dropped = 0;  // frames a browser missed (it was not writable in time)
  int clients = 0;                   // browsers connected now
  int clients_total = 0;
  std::uint64_t service_errors = 0;  // lws_service() failures (the loop goes on)
  std::string last_browser_status;   // the status text a page last reported back ({"status": ...})
};

class ViewServer {
 public:
  // Binds and starts the server thread; throws std::runtime_error naming the address when it
  // cannot listen, or when the page's assets or the Debian JavaScript packages are missing.
  ViewServer(const ViewServerConfig& config, ViewCallbacks callbacks);
  ~ViewServer();
  ViewServer(const ViewServer&) = delete;
  ViewServer& operator=(const ViewServer&) = delete;
  ViewServerStats stats() const;
  std::string url() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace haptic::firmware
