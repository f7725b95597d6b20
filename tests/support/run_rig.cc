// Test support: running the rig binary.
#include "tests/support/run_rig.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <gtest/gtest.h>

namespace rig::testing {

CommandResult RunRig(const std::string& args) {
  const char* bin = std::getenv("RIG_BINARY");
  EXPECT_NE(bin, nullptr) << "RIG_BINARY is not set (run through ctest)";
  if (!bin) return {};
  std::string cmd = std::string(bin) + " " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  CommandResult r;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof buf, p)) r.output.append(buf, n);
  int st = pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : (WIFSIGNALED(st) ? 128 + WTERMSIG(st) : -1);
  return r;
}

std::string SourceDir() {
  const char* s = std::getenv("RIG_SOURCE_DIR");
  return s ? s : ".";
}

std::string SharedDir() {
  const char* s = std::getenv("RIG_SHARED_DIR");
  return s ? s : SourceDir() + "/../shared";
}

std::string ReadText(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

std::string FreshTempDir(const std::string& name) {
  auto p = std::filesystem::temp_directory_path() / fmt::format("rig_{}_{}", name, ::getpid());
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p.string();
}

}  // namespace rig::testing

#include <fcntl.h>

#include <fstream>
#include <set>
#include <map>
#include <sstream>

#include "config/config.h"

namespace rig::testing {

pid_t SpawnRig(const std::vector<std::string>& args, const std::string& log_path) {
  const char* bin = std::getenv("RIG_BINARY");
  EXPECT_NE(bin, nullptr);
  std::vector<std::string> all = {bin};
  all.insert(all.end(), args.begin(), args.end());
  pid_t pid = fork();
  if (pid == 0) {
    int fd = open(log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    if (fd >= 0) {
      dup2(fd, 1);
      dup2(fd, 2);
    }
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(bin, argv.data());
    _exit(127);
  }
  return pid;
}

int WaitRig(pid_t pid) {
  int st = 0;
  waitpid(pid, &st, 0);
  return WIFEXITED(st) ? WEXITSTATUS(st) : (WIFSIGNALED(st) ? 128 + WTERMSIG(st) : -1);
}

std::string WriteSimConfig(const std::string& dir, const std::string& extra) {
  ConfigResult base = LoadConfig(SourceDir() + "/config/sim.toml");
  EXPECT_TRUE(base.ok());
  // Apply `extra` by parsing base + extra as one document is not possible with repeated
  // tables, so parse `extra` on its own over the resolved base.
  std::string merged = ToToml(base.config);
  std::istringstream in(extra);
  std::string line, table;
  std::map<std::string, std::vector<std::string>> adds;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    if (line[0] == '[') {
      table = line.substr(1, line.find(']') - 1);
      continue;
    }
    adds[table].push_back(line);
  }
  // Rebuild: for each table in the base text, drop keys that `extra` sets, append its lines.
  std::istringstream bin(merged);
  std::ostringstream out;
  std::string current;
  std::set<std::string> done;
  auto flush = [&](const std::string& t) {
    if (done.count(t)) return;
    for (const auto& l : adds[t]) out << l << "\n";
    done.insert(t);
  };
  while (std::getline(bin, line)) {
    line.erase(0, line.find_first_not_of(" \t") == std::string::npos ? line.size()
                                                                      : line.find_first_not_of(" \t"));
    if (!line.empty() && line[0] == '[') {
      flush(current);
      current = line.substr(1, line.find(']') - 1);
      out << line << "\n";
      continue;
    }
    std::string key = line.substr(0, line.find('='));
    while (!key.empty() && key.back() == ' ') key.pop_back();
    bool replaced = false;
    for (const auto& l : adds[current]) {
      std::string k = l.substr(0, l.find('='));
      while (!k.empty() && k.back() == ' ') k.pop_back();
      if (k == key) replaced = true;
    }
    if (!replaced) out << line << "\n";
  }
  flush(current);
  for (const auto& [t, lines] : adds) {
    if (done.count(t)) continue;
    out << "[" << t << "]\n";
    for (const auto& l : lines) out << l << "\n";
  }
  std::string path = dir + "/sim.toml";
  std::ofstream(path) << out.str();
  return path;
}

}  // namespace rig::testing
