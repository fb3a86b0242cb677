#include "firmware/view/server.hpp"

#include <arpa/inet.h>
#include <libwebsockets.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <vector>

#include "platform/clock.hpp"
#include "platform/install_paths.hpp"

namespace haptic::firmware {

namespace {
struct Session {  // per browser (zeroed by lws)
  std::uint64_t sent_seq;
  bool scene_sent;
};
struct StatusSession {  // per GET /status.json (zeroed by lws)
  std::string* body;
};
int view_callback(lws* wsi, lws_callback_reasons reason, void* user, void* in, size_t len);
int status_callback(lws* wsi, lws_callback_reasons reason, void* user, void* in, size_t len);
}  // namespace

struct ViewServer::Impl {
  ViewServerConfig cfg;
  ViewCallbacks cb;
  lws_protocols protocols[4] = {};
  lws_http_mount m_root{}, m_three{}, m_chart{}, m_status{};
  lws_context* ctx = nullptr;
  std::atomic<bool> stop{false};
  std::thread service, timer;
  // Only touched on the service thread:
  std::string frame;
  std::uint64_t frame_seq = 0;
  std::string incoming;
  // Read by stats() from any thread:
  std::atomic<std::uint64_t> frames{0}, sent{0}, dropped{0};
  std::atomic<int> clients{0}, clients_total{0};
  std::atomic<std::uint64_t> service_errors{0};
  mutable std::mutex status_mutex;  // the non-RT server thread and stats() readers only
  std::string browser_status;

  void on_message(const std::string& msg) {
    const auto j = nlohmann::json::parse(msg, nullptr, false);
    if (!j.is_discarded() && j.is_object() && j.contains("status") && j["status"].is_string()) {
      std::lock_guard<std::mutex> lock(status_mutex);
      browser_status = j["status"].get<std::string>();
      return;
    }
    if (cb.on_message) cb.on_message(msg);
  }

  int write_text(lws* wsi, const std::string& s) {
    std::vector<unsigned char> buf(LWS_PRE + s.size());
    std::memcpy(buf.data() + LWS_PRE, s.data(), s.size());
    return lws_write(wsi, buf.data() + LWS_PRE, s.size(), LWS_WRITE_TEXT) < static_cast<int>(s.size()) ? -1 : 0;
  }

  int on_writable(lws* wsi, Session& ss) {
    if (!ss.scene_sent) {
      ss.scene_sent = true;
      ss.sent_seq = frame_seq > 0 ? frame_seq - 1 : 0;
      if (write_text(wsi, cb.scene()) < 0) return -1;
      lws_callback_on_writable(wsi);
      return 0;
    }
    if (ss.sent_seq >= frame_seq || frame.empty()) return 0;
    if (frame_seq - ss.sent_seq > 1) dropped.fetch_add(frame_seq - ss.sent_seq - 1, std::memory_order_relaxed);
    ss.sent_seq = frame_seq;
    sent.fetch_add(1, std::memory_order_relaxed);
    return write_text(wsi, frame);
  }

  void on_tick_request() {  // the timer woke the service thread: offer a new frame
    std::string f;
    if (stop.load(std::memory_order_acquire) || !cb.next_frame || !cb.next_frame(f)) return;
    if (!f.empty() && f.back() == '}')  // the server's own count of frames browsers missed
      f.insert(f.size() - 1, ",\"server_dropped\":" + std::to_string(dropped.load(std::memory_order_relaxed)));
    frame = std::move(f);
    ++frame_seq;
    frames.fetch_add(1, std::memory_order_relaxed);
    lws_callback_on_writable_all_protocol(ctx, &protocols[1]);
  }
};

namespace {

int view_callback(lws* wsi, lws_callback_reasons reason, void* user, void* in, size_t len) {
  auto* impl = static_cast<ViewServer::Impl*>(lws_context_user(lws_get_context(wsi)));
  auto* ss = static_cast<Session*>(user);
  switch (reason) {
    case LWS_CALLBACK_ESTABLISHED:
      ss->scene_sent = false;
      ss->sent_seq = 0;
      impl->clients.fetch_add(1);
      impl->clients_total.fetch_add(1);
      lws_callback_on_writable(wsi);
      break;
    case LWS_CALLBACK_CLOSED:
      impl->clients.fetch_sub(1);
      break;
    case LWS_CALLBACK_SERVER_WRITEABLE:
      return impl->on_writable(wsi, *ss);
    case LWS_CALLBACK_RECEIVE:
      impl->incoming.append(static_cast<const char*>(in), len);
      if (lws_is_final_fragment(wsi)) {
        impl->on_message(impl->incoming);
        impl->incoming.clear();
      }
      break;
    case LWS_CALLBACK_EVENT_WAIT_CANCELLED:
      impl->on_tick_request();
      break;
    default:
      break;
  }
  return 0;
}

// GET /status.json: the status callback's JSON, answered on the server thread.
int status_callback(lws* wsi, lws_callback_reasons reason, void* user, void* in, size_t len) {
  auto* impl = static_cast<ViewServer::Impl*>(lws_context_user(lws_get_context(wsi)));
  auto* ss = static_cast<StatusSession*>(user);
  switch (reason) {
    case LWS_CALLBACK_HTTP: {
      delete ss->body;
      ss->body = new std::string(impl->cb.status ? impl->cb.status() : std::string("{}"));
      unsigned char buf[LWS_PRE + 512];
      unsigned char *start = buf + LWS_PRE, *p = start, *end = buf + sizeof buf - 1;
      static const char no_store[] = "no-store";
      if (lws_add_http_common_headers(wsi, HTTP_STATUS_OK, "application/json", ss->body->size(), &p, end) ||
          lws_add_http_header_by_token(wsi, WSI_TOKEN_HTTP_CACHE_CONTROL, reinterpret_cast<const unsigned char*>(no_store),
                                       static_cast<int>(sizeof no_store - 1), &p, end) ||
          lws_finalize_write_http_header(wsi, start, &p, end))
        return 1;
      lws_callback_on_writable(wsi);
      return 0;
    }
    case LWS_CALLBACK_HTTP_WRITEABLE: {
      if (ss->body == nullptr) break;
      std::vector<unsigned char> buf(LWS_PRE + ss->body->size());
      std::memcpy(buf.data() + LWS_PRE, ss->body->data(), ss->body->size());
      const int n = lws_write(wsi, buf.data() + LWS_PRE, ss->body->size(), LWS_WRITE_HTTP_FINAL);
      delete ss->body;
      ss->body = nullptr;
      if (n < 0) return -1;
      if (lws_http_transaction_completed(wsi)) return -1;
      return 0;
    }
    case LWS_CALLBACK_CLOSED_HTTP:
      delete ss->body;
      ss->body = nullptr;
      break;
    default:
      break;
  }
  return lws_callback_http_dummy(wsi, reason, user, in, len);
}

void mount(lws_http_mount& m, const char* point, const std::string& origin, const char* def, const lws_http_mount* next) {
  m.mount_next = next;
  m.mountpoint = point;
  m.origin = origin.c_str();
  m.def = def;
  m.origin_protocol = LWSMPRO_FILE;
  m.mountpoint_len = static_cast<unsigned char>(std::strlen(point));
}

// An IPv4 address in dotted form: the only kind of station.view_bind / --view-bind we accept
// (libwebsockets would also take an interface name and, when it does not exist, keep retrying
// in the background instead of failing).
bool is_ipv4_address(const std::string& s) {
  in_addr a{};
  return inet_pton(AF_INET, s.c_str(), &a) == 1;
}

void require_file(const std::string& path, const std::string& hint) {
  if (!std::filesystem::exists(path)) throw std::runtime_error("live view: " + path + " not found (" + hint + ")");
}

}  // namespace

ViewServer::ViewServer(const ViewServerConfig& config, ViewCallbacks callbacks) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.cfg = config;
  m.cb = std::move(callbacks);
  if (!is_ipv4_address(m.cfg.bind))
    throw std::runtime_error("live view: " + m.cfg.bind + " is not an IPv4 address of this machine (station.view_bind / --view-bind, e.g. 127.0.0.1 or 0.0.0.0)");
  if (m.cfg.assets_dir.empty()) m.cfg.assets_dir = platform::tools_dir() + "/view";
  require_file(m.cfg.assets_dir + "/index.html", "the page: tools/view, installed under share/haptic/tools/view; HAPTIC_TOOLS_DIR overrides");
  require_file(m.cfg.three_dir + "/three.min.js", "apt-get install libjs-three");
  require_file(m.cfg.chart_dir + "/chart.min.js", "apt-get install libjs-chart.js");
  mount(m.m_chart, "/chart", m.cfg.chart_dir, nullptr, nullptr);
  mount(m.m_three, "/three", m.cfg.three_dir, nullptr, &m.m_chart);
  mount(m.m_root, "/", m.cfg.assets_dir, "index.html", &m.m_three);
  if (m.cb.status) {  // the most specific mount wins: /status.json before the page's "/"
    static const std::string status_protocol = "haptic-status";
    mount(m.m_status, "/status.json", status_protocol, nullptr, &m.m_chart);
    m.m_status.origin_protocol = LWSMPRO_CALLBACK;
    m.m_three.mount_next = &m.m_status;
  }
  m.protocols[0] = {"http", lws_callback_http_dummy, 0, 0, 0, nullptr, 0};
  m.protocols[1] = {"haptic-view", view_callback, sizeof(Session), 4096, 0, nullptr, 0};
  m.protocols[2] = {"haptic-status", status_callback, sizeof(StatusSession), 0, 0, nullptr, 0};
  lws_set_log_level(LLL_ERR, nullptr);
  lws_context_creation_info info;
  std::memset(&info, 0, sizeof info);
  info.port = m.cfg.port;
  info.iface = m.cfg.bind.c_str();
  info.protocols = m.protocols;
  info.mounts = &m.m_root;
  info.user = &m;
  info.options = LWS_SERVER_OPTION_DISABLE_IPV6 | LWS_SERVER_OPTION_FAIL_UPON_UNABLE_TO_BIND;
  m.ctx = lws_create_context(&info);
  if (!m.ctx) throw std::runtime_error("live view: cannot listen on " + m.cfg.bind + ":" + std::to_string(m.cfg.port) + " (port in use, or not an address of this machine? station.view_port / station.view_bind, --view-port / --view-bind)");
  m.service = std::thread([&m] {
    while (!m.stop.load(std::memory_order_acquire))
      if (lws_service(m.ctx, 0) < 0) {  // e.g. interrupted: count it, go on (bounded by the stop flag)
        m.service_errors.fetch_add(1, std::memory_order_relaxed);
        platform::sleep_until_monotonic_ns(platform::monotonic_ns() + 1'000'000);
      }
  });
  m.timer = std::thread([&m] {
    const auto period = static_cast<std::int64_t>(1e9 / m.cfg.rate_hz);
    std::int64_t next = platform::monotonic_ns();
    while (!m.stop.load(std::memory_order_acquire)) {
      next += period;
      platform::sleep_until_monotonic_ns(next);
      lws_cancel_service(m.ctx);
    }
  });
}

ViewServer::~ViewServer() {
  Impl& m = *impl_;
  m.stop.store(true, std::memory_order_release);
  if (m.timer.joinable()) m.timer.join();
  lws_cancel_service(m.ctx);
  if (m.service.joinable()) m.service.join();
  lws_context_destroy(m.ctx);
}

ViewServerStats ViewServer::stats() const {
  ViewServerStats s;
  s.frames = impl_->frames.load();
  s.frames_sent = impl_->sent.load();
  s.frames_dropped = impl_->dropped.load();
  s.clients = impl_->clients.load();
  s.clients_total = impl_->clients_total.load();
  s.service_errors = impl_->service_errors.load();
  std::lock_guard<std::mutex> lock(impl_->status_mutex);
  s.last_browser_status = impl_->browser_status;
  return s;
}

std::string ViewServer::url() const { return "http://" + impl_->cfg.bind + ":" + std::to_string(impl_->cfg.port) + "/"; }

}  // namespace haptic::firmware
