// Module loggers sharing one set of sinks.
#include "config/log.h"

#include <cstdlib>
#include <mutex>
#include <vector>

#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>

#include "config/console.h"

namespace rig {
namespace {

// The console sink: each line is written with the progress bar erased and drawn again after
// it (config/console.h), so a log line never lands on the end of a bar.
class BarAwareSink final : public spdlog::sinks::sink {
 public:
  explicit BarAwareSink(spdlog::sink_ptr inner) : inner_(std::move(inner)) {}
  void log(const spdlog::details::log_msg& msg) override {
    console_internal::WithBarErased([&] {
      inner_->log(msg);
      inner_->flush();
    });
  }
  void flush() override { inner_->flush(); }
  void set_pattern(const std::string& pattern) override { inner_->set_pattern(pattern); }
  void set_formatter(std::unique_ptr<spdlog::formatter> f) override {
    inner_->set_formatter(std::move(f));
  }

 private:
  spdlog::sink_ptr inner_;
};

struct Registry {
  std::mutex mu;
  std::vector<spdlog::sink_ptr> sinks;
  spdlog::level::level_enum level = spdlog::level::info;
  bool level_from_env = false;
};

Registry& R() {
  static Registry* r = [] {
    auto* reg = new Registry;
    auto console = std::make_shared<BarAwareSink>(
        std::make_shared<spdlog::sinks::stderr_color_sink_mt>());
    console->set_pattern("%^%L%$ %-7n %v");
    reg->sinks.push_back(console);
    if (const char* env = std::getenv("RIG_LOG_LEVEL")) {
      auto lvl = spdlog::level::from_str(env);
      if (lvl != spdlog::level::off || std::string(env) == "off") reg->level = lvl;
    }
    return reg;
  }();
  return *r;
}

}  // namespace

std::shared_ptr<spdlog::logger> Log(const std::string& module) {
  Registry& r = R();
  std::lock_guard lock(r.mu);
  if (auto l = spdlog::get(module)) return l;
  auto l = std::make_shared<spdlog::logger>(module, r.sinks.begin(), r.sinks.end());
  l->set_level(r.level);
  // With a log file, every line is flushed (AddLogFile); before one, warnings and errors.
  bool has_file = false;
  for (const auto& sink : r.sinks)
    has_file = has_file || std::dynamic_pointer_cast<spdlog::sinks::basic_file_sink_mt>(sink) != nullptr;
  l->flush_on(has_file ? spdlog::level::trace : spdlog::level::warn);
  spdlog::register_logger(l);
  return l;
}

bool SetLogLevel(const std::string& level) {
  Registry& r = R();
  std::string name = level;
  if (name.empty()) {
    const char* env = std::getenv("RIG_LOG_LEVEL");
    name = env ? env : "info";
  }
  auto lvl = spdlog::level::from_str(name);
  if (lvl == spdlog::level::off && name != "off") return false;
  std::lock_guard lock(r.mu);
  r.level = lvl;
  spdlog::apply_all([&](std::shared_ptr<spdlog::logger> l) { l->set_level(lvl); });
  return true;
}

bool AddLogFile(const std::string& path) {
  Registry& r = R();
  {
    // A session opened again in the same process (the capture service, a resume after a
    // capture, the fuzzers) logs to its file once, and does not open it again.
    std::lock_guard lock(r.mu);
    for (const auto& s : r.sinks)
      if (auto f = std::dynamic_pointer_cast<spdlog::sinks::basic_file_sink_mt>(s);
          f && f->filename() == path)
        return true;
  }
  spdlog::sink_ptr file;
  try {
    file = std::make_shared<spdlog::sinks::basic_file_sink_mt>(path, false);
  } catch (const spdlog::spdlog_ex&) {
    return false;
  }
  file->set_pattern("%Y-%m-%dT%H:%M:%S.%e %L %-7n %v");
  std::lock_guard lock(r.mu);
  r.sinks.push_back(file);
  spdlog::apply_all([&](std::shared_ptr<spdlog::logger> l) {
    l->sinks().push_back(file);
    // Every line reaches the file as it is logged: log.txt is a live view (`tail -f`), and
    // a crash loses no line.
    l->flush_on(spdlog::level::trace);
  });
  return true;
}

}  // namespace rig
