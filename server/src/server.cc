#include "npfkct/server/server.h"

#include <fcntl.h>
#include <httplib.h>
#include <sched.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <sstream>

#include "npfkct/server/codec.h"
#include "npfkct/server/filter_samplers.h"
#include "npfkct/sim/frame_io.h"
#include "npfkct/sim/scenario.h"

namespace npfkct::server {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr int kMaxJsonDepth = 64;

std::string NewSessionId() {
  static thread_local std::mt19937_64 gen(std::random_device{}());
  char buf[33];
  std::snprintf(buf, sizeof buf, "%016llx%016llx", static_cast<unsigned long long>(gen()),
                static_cast<unsigned long long>(gen()));
  return buf;
}

bool ValidSessionId(const std::string& id) {
  if (id.size() != 32) return false;
  return std::all_of(id.begin(), id.end(),
                     [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

// Rejects bodies nested deeper than kMaxJsonDepth before the parser sees them.
bool DepthWithin(const std::string& body, int limit) {
  int depth = 0;
  bool in_string = false, escaped = false;
  for (char c : body) {
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > limit) return false;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return true;
}

StatusOr<json> ParseBody(const std::string& body, bool allow_empty) {
  if (body.empty() || body.find_first_not_of(" \t\r\n") == std::string::npos) {
    if (allow_empty) return json::object();
    return InvalidArgumentError("body: expected a JSON object");
  }
  if (!DepthWithin(body, kMaxJsonDepth)) {
    return InvalidArgumentError("body: nested deeper than " + std::to_string(kMaxJsonDepth) +
                                " levels");
  }
  json j = json::parse(body, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return InvalidArgumentError("body: not valid JSON");
  if (!j.is_object()) return InvalidArgumentError("body: expected a JSON object");
  return j;
}

Status CheckTopKeys(const json& j, const std::set<std::string>& known) {
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (!known.count(it.key())) return InvalidArgumentError(it.key() + ": unknown field");
  }
  return OkStatus();
}

// Runs the search loop under SCHED_BATCH: planners keep their fair share of the CPU, but threads
// that wake up to parse a request or send a reply (SCHED_OTHER) preempt them, so that many sessions
// planning on few cores delay each other's responses less. The policy is restored on scope exit
// (an unprivileged thread may switch back to SCHED_OTHER).
class BatchScheduling {
 public:
  BatchScheduling() {
    sched_param p{};
    active_ = sched_setscheduler(0, SCHED_BATCH, &p) == 0;
  }
  ~BatchScheduling() {
    if (!active_) return;
    sched_param p{};
    sched_setscheduler(0, SCHED_OTHER, &p);
  }
  BatchScheduling(const BatchScheduling&) = delete;
  BatchScheduling& operator=(const BatchScheduling&) = delete;

 private:
  bool active_ = false;
};

// Fsyncs a file or directory; false on failure.
bool Fsync(const std::string& path, bool directory) {
  const int fd = ::open(path.c_str(), directory ? O_RDONLY | O_DIRECTORY : O_RDONLY);
  if (fd < 0) return false;
  const bool ok = ::fsync(fd) == 0;
  ::close(fd);
  return ok;
}

}  // namespace

Status ServerOptions::Validate() const {
  if (port < 0 || port > 65535) return InvalidArgumentError("port: must be in [0, 65535]");
  if (!(session_ttl_seconds > 0.0)) return InvalidArgumentError("session_ttl: must be > 0");
  if (max_sessions < 1) return InvalidArgumentError("max_sessions: must be >= 1");
  if (threads < 1 || threads > 1024) return InvalidArgumentError("threads: must be in [1, 1024]");
  if (max_body_bytes < 1024) return InvalidArgumentError("max_body: must be >= 1 KiB");
  if (!(default_plan_ms > 0.0) || !(max_plan_ms >= default_plan_ms)) {
    return InvalidArgumentError("plan budgets: need 0 < default <= max");
  }
  if (max_particles < 1) return InvalidArgumentError("max_particles: must be >= 1");
  return OkStatus();
}

struct Server::Impl {
  ServerOptions options;
  SamplerFactory* samplers = nullptr;
  httplib::Server http;
  Metrics metrics;
  std::shared_mutex sessions_mutex;
  std::map<std::string, std::shared_ptr<Session>> sessions;
  std::thread serve_thread, reaper_thread;
  std::mutex stop_mutex;
  std::condition_variable stop_cv;
  bool stopping = false;

  // ---- sessions ----

  std::shared_ptr<Session> Find(const std::string& id) {
    std::shared_lock lock(sessions_mutex);
    auto it = sessions.find(id);
    return it == sessions.end() ? nullptr : it->second;
  }

  bool StillLive(const std::string& id, const Session* s) {
    std::shared_lock lock(sessions_mutex);
    auto it = sessions.find(id);
    return it != sessions.end() && it->second.get() == s;
  }

  std::string SnapshotPath(const std::string& id) const {
    return options.state_dir + "/" + id + ".json";
  }

  // Writes the snapshot durably before the caller acknowledges the request.
  Status Persist(const Session& s) {
    if (options.state_dir.empty()) return OkStatus();
    const std::string path = SnapshotPath(s.id());
    const std::string tmp = path + ".tmp";
    {
      std::ofstream out(tmp, std::ios::trunc);
      out << s.Snapshot().dump();
      out.flush();
      if (!out) return Status(StatusCode::kUnavailable, "cannot write session snapshot");
    }
    if (!Fsync(tmp, false) || std::rename(tmp.c_str(), path.c_str()) != 0 ||
        !Fsync(options.state_dir, true)) {
      return Status(StatusCode::kUnavailable, "cannot store session snapshot");
    }
    return OkStatus();
  }

  void Unpersist(const std::string& id) {
    if (options.state_dir.empty()) return;
    std::error_code ec;
    fs::remove(SnapshotPath(id), ec);
    Fsync(options.state_dir, true);
  }

  int RestoreAll() {
    if (options.state_dir.empty()) return 0;
    int restored = 0;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(options.state_dir, ec)) {
      const std::string name = entry.path().filename().string();
      if (entry.path().extension() != ".json") continue;
      std::ifstream in(entry.path());
      std::stringstream buffer;
      buffer << in.rdbuf();
      json j = json::parse(buffer.str(), nullptr, false);
      StatusOr<std::unique_ptr<Session>> s = Status(StatusCode::kDataLoss, "not JSON");
      if (!j.is_discarded()) {
        try {
          s = Session::Restore(j, *samplers);
        } catch (const std::exception& e) {
          s = Status(StatusCode::kDataLoss, std::string("snapshot: ") + e.what());
        }
      }
      if (!s.ok() || !ValidSessionId((*s)->id()) || name != (*s)->id() + ".json") {
        spdlog::warn("skipping snapshot {}: {}", name,
                     s.ok() ? "name does not match its id" : s.status().ToString());
        continue;
      }
      std::shared_ptr<Session> session = std::move(s).value();
      sessions[session->id()] = session;
      ++restored;
    }
    metrics.SetSessions(static_cast<int>(sessions.size()));
    return restored;
  }

  void Reap() {
    std::vector<std::string> expired;
    {
      std::shared_lock lock(sessions_mutex);
      for (const auto& [id, s] : sessions) {
        std::unique_lock<std::mutex> session_lock(s->mutex(), std::try_to_lock);
        if (session_lock.owns_lock() && s->IdleSeconds() > s->ttl_seconds()) expired.push_back(id);
      }
    }
    for (const std::string& id : expired) {
      {
        std::unique_lock lock(sessions_mutex);
        sessions.erase(id);
        metrics.SetSessions(static_cast<int>(sessions.size()));
      }
      Unpersist(id);
      metrics.CountExpired();
      spdlog::info("session {} expired", id);
    }
  }

  // ---- requests ----

  StatusOr<json> CreateSession(const json& body) {
    if (Status s =
            CheckTopKeys(body, {"displayName", "world", "target", "planner", "seed", "ttlSeconds"});
        !s.ok()) {
      return s;
    }
    std::string display_name;
    if (body.contains("displayName")) {
      if (!body.at("displayName").is_string() ||
          body.at("displayName").get<std::string>().size() > 200) {
        return InvalidArgumentError("displayName: expected a string of at most 200 characters");
      }
      display_name = body.at("displayName").get<std::string>();
    }
    if (!body.contains("world")) return InvalidArgumentError("world: missing");
    auto scenario = sim::ParseWorldSpec(body.at("world"), "world");
    if (!scenario.ok()) return scenario.status();
    auto world = sim::InitialWorld(*scenario);
    if (!world.ok()) return InvalidArgumentError("world." + world.status().message());
    TargetSpec target;
    if (body.contains("target")) {
      const json& t = body.at("target");
      if (!t.is_object()) return InvalidArgumentError("target: expected an object");
      if (Status s = CheckTopKeys(t, {"description", "photos"}); !s.ok()) {
        return InvalidArgumentError("target." + s.message());
      }
      if (t.contains("description") && !t.at("description").is_string()) {
        return InvalidArgumentError("target.description: expected a string");
      }
      if (t.contains("photos") && (!t.at("photos").is_array() || t.at("photos").size() > 16)) {
        return InvalidArgumentError("target.photos: expected an array of at most 16 images");
      }
      target.description = t.value("description", std::string());
      if (t.contains("photos")) {
        const json& photos = t.at("photos");
        for (size_t i = 0; i < photos.size(); ++i) {
          if (!photos[i].is_string()) {
            return InvalidArgumentError("target.photos[" + std::to_string(i) +
                                        "]: expected a base64 PNG or JPEG string");
          }
          target.photos.push_back(photos[i].get<std::string>());
        }
      }
    }
    PlannerSpec spec;
    if (body.contains("planner")) {
      const json& p = body.at("planner");
      if (!p.is_object()) return InvalidArgumentError("planner: expected an object");
      if (Status s = CheckTopKeys(p, {"name", "particles", "options", "modelPath"}); !s.ok()) {
        return InvalidArgumentError("planner." + s.message());
      }
      if (p.contains("name")) {
        if (!p.at("name").is_string())
          return InvalidArgumentError("planner.name: expected a string");
        spec.name = p.at("name").get<std::string>();
      }
      if (p.contains("particles")) {
        const json& n = p.at("particles");
        if (!n.is_number_integer() || n.get<int64_t>() < 1 ||
            n.get<int64_t>() > options.max_particles) {
          return InvalidArgumentError("planner.particles: expected an integer in [1, " +
                                      std::to_string(options.max_particles) + "]");
        }
        spec.particles = n.get<int>();
      }
      if (p.contains("modelPath")) {
        if (!p.at("modelPath").is_string()) {
          return InvalidArgumentError("planner.modelPath: expected a string");
        }
        spec.model_path = p.at("modelPath").get<std::string>();
      }
      if (p.contains("options")) {
        const json& o = p.at("options");
        if (!o.is_object()) return InvalidArgumentError("planner.options: expected an object");
        for (auto it = o.begin(); it != o.end(); ++it) {
          const std::string key = "planner.options." + it.key();
          double v;
          if (it.value().is_boolean()) {
            v = it.value().get<bool>() ? 1.0 : 0.0;
          } else if (it.value().is_number()) {
            v = it.value().get<double>();
            if (!std::isfinite(v)) return InvalidArgumentError(key + ": not finite");
          } else {
            return InvalidArgumentError(key + ": expected a number or a boolean");
          }
          spec.options.emplace_back(SnakeCase(it.key()), v);
        }
        spec.options_json = o;
      }
    }
    uint64_t seed = std::random_device{}();
    if (body.contains("seed")) {
      const json& s = body.at("seed");
      if (s.is_number_unsigned()) {
        seed = s.get<uint64_t>();
      } else if (s.is_string() && !s.get<std::string>().empty() &&
                 s.get<std::string>().size() <= 20 &&
                 s.get<std::string>().find_first_not_of("0123456789") == std::string::npos) {
        try {
          seed = std::stoull(s.get<std::string>());
        } catch (...) {
          return InvalidArgumentError("seed: out of range");
        }
      } else {
        return InvalidArgumentError(
            "seed: expected a non-negative integer (or its decimal string)");
      }
    }
    double ttl = options.session_ttl_seconds;
    if (body.contains("ttlSeconds")) {
      const json& t = body.at("ttlSeconds");
      if (!t.is_number() || !(t.get<double>() > 0.0) ||
          t.get<double>() > options.session_ttl_seconds) {
        return InvalidArgumentError("ttlSeconds: expected a number in (0, " +
                                    std::to_string(options.session_ttl_seconds) + "]");
      }
      ttl = t.get<double>();
    }
    {
      std::shared_lock lock(sessions_mutex);
      if (static_cast<int>(sessions.size()) >= options.max_sessions) {
        return ResourceExhaustedError("sessions: the server holds the maximum of " +
                                      std::to_string(options.max_sessions));
      }
    }
    auto created = Session::Create(NewSessionId(), display_name, std::move(world).value(), spec,
                                   std::move(target), seed, ttl, *samplers);
    if (!created.ok()) return created.status();
    std::shared_ptr<Session> session = std::move(created).value();
    std::lock_guard<std::mutex> session_lock(session->mutex());
    if (Status s = Persist(*session); !s.ok()) return s;
    {
      std::unique_lock lock(sessions_mutex);
      if (static_cast<int>(sessions.size()) >= options.max_sessions) {
        Unpersist(session->id());
        return ResourceExhaustedError("sessions: the server holds the maximum of " +
                                      std::to_string(options.max_sessions));
      }
      sessions[session->id()] = session;
      metrics.SetSessions(static_cast<int>(sessions.size()));
    }
    spdlog::info("session {} created (planner {})", session->id(), spec.name);
    return session->Resource();
  }

  StatusOr<Budget> ParseBudget(const json& body) {
    if (Status s = CheckTopKeys(body, {"budget"}); !s.ok()) return s;
    Budget b{options.default_plan_ms, 0};
    if (!body.contains("budget")) return b;
    const json& j = body.at("budget");
    if (!j.is_object()) return InvalidArgumentError("budget: expected an object");
    if (Status s = CheckTopKeys(j, {"timeMs", "simulations"}); !s.ok()) {
      return InvalidArgumentError("budget." + s.message());
    }
    b.time_ms = 0.0;
    if (j.contains("timeMs")) {
      const json& t = j.at("timeMs");
      if (!t.is_number() || !(t.get<double>() >= 0.0) || t.get<double>() > options.max_plan_ms) {
        return InvalidArgumentError("budget.timeMs: expected a number in [0, " +
                                    std::to_string(static_cast<int64_t>(options.max_plan_ms)) +
                                    "]");
      }
      b.time_ms = t.get<double>();
    }
    if (j.contains("simulations")) {
      const json& n = j.at("simulations");
      if (!n.is_number_integer() || n.get<int64_t>() < 0 ||
          n.get<int64_t>() > options.max_plan_simulations) {
        return InvalidArgumentError("budget.simulations: expected an integer in [0, " +
                                    std::to_string(options.max_plan_simulations) + "]");
      }
      b.max_simulations = n.get<int64_t>();
    }
    if (b.time_ms == 0.0 && b.max_simulations == 0) {
      if (j.contains("timeMs") || j.contains("simulations")) {
        return InvalidArgumentError("budget: set timeMs and/or simulations above 0");
      }
      b.time_ms = options.default_plan_ms;
    }
    // A simulation budget alone is still capped in time, so no request can hold a worker forever.
    if (b.time_ms == 0.0) b.time_ms = options.max_plan_ms;
    return b;
  }
};

Server::Server(ServerOptions options)
    : options_(std::move(options)), samplers_(FilterSamplerFactory()) {}

Server::~Server() { Stop(); }

Status Server::Start() {
  if (Status s = options_.Validate(); !s.ok()) return s;
  impl_ = std::make_unique<Impl>();
  Impl& im = *impl_;
  im.options = options_;
  im.samplers = &samplers_;
  if (!options_.state_dir.empty()) {
    std::error_code ec;
    fs::create_directories(options_.state_dir, ec);
    if (ec) return InvalidArgumentError("state_dir: cannot create '" + options_.state_dir + "'");
  }
  restored_ = im.RestoreAll();
  if (restored_ > 0) spdlog::info("restored {} sessions from {}", restored_, options_.state_dir);

  httplib::Server& http = im.http;
  const int threads = options_.threads;
  http.new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
  http.set_payload_max_length(options_.max_body_bytes);
  // Responses go out as header and body writes: without TCP_NODELAY, Nagle's algorithm holds the
  // body until the client's delayed ACK (40 ms).
  http.set_tcp_nodelay(true);
  http.set_read_timeout(30, 0);
  http.set_write_timeout(30, 0);

  auto reply = [&im](httplib::Response& res, int code, const json& body) {
    res.status = code;
    res.set_content(body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
  };
  auto fail = [&im](httplib::Response& res, const ApiError& e) {
    res.status = HttpStatusOf(e.status.code());
    res.set_content(ErrorBody(e), "application/json");
  };
  // Wraps a handler: authentication, exceptions, metrics.
  auto wrap = [&im, fail](std::string method, std::string route, bool auth, auto handler) {
    return [&im, fail, method, route, auth, handler](const httplib::Request& req,
                                                     httplib::Response& res) {
      const auto start = Clock::now();
      if (auth && !im.options.api_key.empty()) {
        const std::string header = req.get_header_value("Authorization");
        if (header != "Bearer " + im.options.api_key) {
          fail(res, ApiError{Status(StatusCode::kUnauthenticated,
                                    "missing or wrong bearer token (Authorization header)"),
                             ""});
          im.metrics.ObserveRequest(method, route, res.status,
                                    std::chrono::duration<double>(Clock::now() - start).count());
          return;
        }
      }
      try {
        handler(req, res);
      } catch (const json::exception& e) {
        fail(res, ApiError{InvalidArgumentError(std::string("body: ") + e.what()), ""});
      } catch (const std::bad_alloc&) {
        fail(res, ApiError{ResourceExhaustedError("out of memory"), ""});
      } catch (const std::exception& e) {
        spdlog::error("{} {}: {}", method, req.path, e.what());
        fail(res, ApiError{InternalError(e.what()), ""});
      }
      im.metrics.ObserveRequest(method, route, res.status,
                                std::chrono::duration<double>(Clock::now() - start).count());
    };
  };
  auto session_of = [&im, fail](const httplib::Request& req,
                                httplib::Response& res) -> std::shared_ptr<Session> {
    const std::string id = req.matches[1];
    std::shared_ptr<Session> s = ValidSessionId(id) ? im.Find(id) : nullptr;
    if (!s) fail(res, ApiError{NotFoundError("sessions/" + id + " not found"), ""});
    return s;
  };

  http.Get("/healthz",
           wrap("GET", "/healthz", false, [reply](const httplib::Request&, httplib::Response& res) {
             reply(res, 200, {{"status", "SERVING"}});
           }));
  http.Get("/metrics",
           wrap("GET", "/metrics", false, [&im](const httplib::Request&, httplib::Response& res) {
             res.set_content(im.metrics.Render(), "text/plain; version=0.0.4; charset=utf-8");
           }));
  http.Post("/v1/sessions",
            wrap("POST", "/v1/sessions", true,
                 [&im, reply, fail](const httplib::Request& req, httplib::Response& res) {
                   auto body = ParseBody(req.body, false);
                   if (!body.ok()) return fail(res, ApiError::From(body.status()));
                   auto created = im.CreateSession(*body);
                   if (!created.ok()) return fail(res, ApiError::From(created.status()));
                   reply(res, 200, *created);
                 }));
  http.Get(
      "/v1/sessions",
      wrap("GET", "/v1/sessions", true,
           [&im, reply, fail](const httplib::Request& req, httplib::Response& res) {
             int page_size = 50;
             if (req.has_param("pageSize")) {
               const std::string v = req.get_param_value("pageSize");
               if (v.empty() || v.size() > 4 ||
                   v.find_first_not_of("0123456789") != std::string::npos || std::stoi(v) < 1 ||
                   std::stoi(v) > 1000) {
                 return fail(
                     res,
                     ApiError{InvalidArgumentError("pageSize: expected an integer in [1, 1000]"),
                              "pageSize"});
               }
               page_size = std::stoi(v);
             }
             const std::string token = req.get_param_value("pageToken");
             std::vector<std::shared_ptr<Session>> page;
             std::string next;
             {
               std::shared_lock lock(im.sessions_mutex);
               auto it = im.sessions.upper_bound(token);
               for (; it != im.sessions.end() && static_cast<int>(page.size()) < page_size; ++it) {
                 page.push_back(it->second);
               }
               if (it != im.sessions.end() && !page.empty()) next = page.back()->id();
             }
             json out;
             out["sessions"] = json::array();
             for (const auto& s : page) {
               std::lock_guard<std::mutex> lock(s->mutex());
               out["sessions"].push_back(s->Resource());
             }
             if (!next.empty()) out["nextPageToken"] = next;
             reply(res, 200, out);
           }));
  http.Get(R"(/v1/sessions/([^/:]+))",
           wrap("GET", "/v1/sessions/{id}", true,
                [&im, reply, session_of](const httplib::Request& req, httplib::Response& res) {
                  auto s = session_of(req, res);
                  if (!s) return;
                  std::lock_guard<std::mutex> lock(s->mutex());
                  s->Touch();
                  reply(res, 200, s->Resource());
                }));
  http.Delete(
      R"(/v1/sessions/([^/:]+))",
      wrap("DELETE", "/v1/sessions/{id}", true,
           [&im, reply, fail](const httplib::Request& req, httplib::Response& res) {
             const std::string id = req.matches[1];
             bool erased = false;
             if (ValidSessionId(id)) {
               std::unique_lock lock(im.sessions_mutex);
               erased = im.sessions.erase(id) > 0;
               im.metrics.SetSessions(static_cast<int>(im.sessions.size()));
             }
             if (!erased) {
               return fail(res, ApiError{NotFoundError("sessions/" + id + " not found"), ""});
             }
             im.Unpersist(id);
             spdlog::info("session {} deleted", id);
             reply(res, 200, json::object());
           }));
  http.Post(
      R"(/v1/sessions/([^/:]+):plan)",
      wrap("POST", "/v1/sessions/{id}:plan", true,
           [&im, reply, fail, session_of](const httplib::Request& req, httplib::Response& res) {
             const auto start = Clock::now();
             auto body = ParseBody(req.body, true);
             if (!body.ok()) return fail(res, ApiError::From(body.status()));
             auto budget = im.ParseBudget(*body);
             if (!budget.ok()) return fail(res, ApiError::From(budget.status()));
             auto s = session_of(req, res);
             if (!s) return;
             std::lock_guard<std::mutex> lock(s->mutex());
             s->Touch();
             StatusOr<json> out = Status(StatusCode::kInternal, "not planned");
             {
               BatchScheduling batch;
               out = s->Plan(*budget);
             }
             if (!out.ok()) return fail(res, ApiError::From(out.status()));
             if (!im.StillLive(s->id(), s.get())) {
               return fail(res, ApiError{Status(StatusCode::kAborted,
                                                "the session was deleted while planning"),
                                         ""});
             }
             if (Status st = im.Persist(*s); !st.ok()) return fail(res, ApiError{st, ""});
             const double total = std::chrono::duration<double>(Clock::now() - start).count();
             const double planning = s->last_planning_ms() / 1000.0;
             im.metrics.ObservePlan(planning, std::max(0.0, total - planning),
                                    (*out)["stats"]["simulations"].get<int64_t>());
             reply(res, 200, *out);
           }));
  http.Post(
      R"(/v1/sessions/([^/:]+):observe)",
      wrap("POST", "/v1/sessions/{id}:observe", true,
           [&im, reply, fail, session_of](const httplib::Request& req, httplib::Response& res) {
             auto body = ParseBody(req.body, false);
             if (!body.ok()) return fail(res, ApiError::From(body.status()));
             auto s = session_of(req, res);
             if (!s) return;
             std::lock_guard<std::mutex> lock(s->mutex());
             s->Touch();
             auto out = s->Observe(*body);
             if (!out.ok()) return fail(res, ApiError::From(out.status()));
             if (!im.StillLive(s->id(), s.get())) {
               return fail(
                   res,
                   ApiError{Status(StatusCode::kAborted, "the session was deleted meanwhile"), ""});
             }
             if (Status st = im.Persist(*s); !st.ok()) return fail(res, ApiError{st, ""});
             reply(res, 200, *out);
           }));
  http.Get(
      R"(/v1/sessions/([^/:]+)/belief)",
      wrap("GET", "/v1/sessions/{id}/belief", true,
           [&im, reply, fail, session_of](const httplib::Request& req, httplib::Response& res) {
             const std::string format =
                 req.has_param("format") ? req.get_param_value("format") : "json";
             if (format != "json" && format != "png") {
               return fail(res, ApiError{InvalidArgumentError("format: expected 'json' or 'png'"),
                                         "format"});
             }
             auto s = session_of(req, res);
             if (!s) return;
             std::lock_guard<std::mutex> lock(s->mutex());
             s->Touch();
             if (format == "json") return reply(res, 200, s->Belief());
             std::vector<uchar> png;
             cv::imencode(".png", sim::RenderGridWorld(s->world(), 150), png);
             res.set_content(std::string(png.begin(), png.end()), "image/png");
           }));
  // Errors produced by the HTTP layer itself (unknown routes, oversized bodies, bad requests).
  http.set_error_handler(
      httplib::Server::HandlerWithResponse([](const httplib::Request& req, httplib::Response& res) {
        if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
        const int code = res.status;
        StatusCode status = StatusCode::kInvalidArgument;
        std::string message = "bad request";
        if (code == 404) {
          status = StatusCode::kNotFound;
          message = "no route for " + req.method + " " + req.path;
        } else if (code == 413) {
          status = StatusCode::kResourceExhausted;
          message = "request body too large";
        } else if (code >= 500) {
          status = StatusCode::kInternal;
          message = "internal error";
        }
        res.set_content(ErrorBody(ApiError{Status(status, message), ""}), "application/json");
        res.status = code;
        return httplib::Server::HandlerResponse::Handled;
      }));
  http.set_exception_handler(
      [fail](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
        fail(res, ApiError{InternalError("unexpected error"), ""});
      });

  port_ = options_.port == 0
              ? http.bind_to_any_port(options_.host)
              : (http.bind_to_port(options_.host, options_.port) ? options_.port : -1);
  if (port_ < 0) {
    return Status(StatusCode::kUnavailable,
                  "cannot bind " + options_.host + ":" + std::to_string(options_.port));
  }
  im.serve_thread = std::thread([&im] { im.http.listen_after_bind(); });
  im.reaper_thread = std::thread([&im] {
    std::unique_lock<std::mutex> lock(im.stop_mutex);
    while (!im.stopping) {
      im.stop_cv.wait_for(lock, std::chrono::milliseconds(500));
      if (im.stopping) break;
      lock.unlock();
      im.Reap();
      lock.lock();
    }
  });
  spdlog::info("npfkct-server listening on {}:{}", options_.host, port_);
  return OkStatus();
}

void Server::Wait() {
  if (!impl_) return;
  std::unique_lock<std::mutex> lock(impl_->stop_mutex);
  impl_->stop_cv.wait(lock, [this] { return impl_->stopping; });
}

void Server::Stop() {
  if (!impl_) return;
  {
    std::lock_guard<std::mutex> lock(impl_->stop_mutex);
    if (impl_->stopping && !impl_->serve_thread.joinable()) return;
    impl_->stopping = true;
  }
  impl_->stop_cv.notify_all();
  impl_->http.stop();
  if (impl_->serve_thread.joinable()) impl_->serve_thread.join();
  if (impl_->reaper_thread.joinable()) impl_->reaper_thread.join();
}

}  // namespace npfkct::server
