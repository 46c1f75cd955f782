// Real processes for the integration and end-to-end tests: vsurg-server started on a SQLite file
// with its ready file, and shell command lines with their output and exit code.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

extern char** environ;

namespace vsurg::test {

struct ServerProcess {
  pid_t pid = -1;
  int grpc_port = 0, udp_port = 0;

  // Starts `binary` (vsurg-server) on `db` and waits for its ready file. Ports 0: any free one;
  // a restart passes the previous ones to come back where the clients expect it.
  static ServerProcess Start(const std::string& binary, const std::filesystem::path& dir,
                             const std::filesystem::path& db, int grpc_port = 0, int udp_port = 0) {
    ServerProcess p;
    const std::string ready = (dir / "ready.json").string();
    std::filesystem::remove(ready);
    std::vector<std::string> args = {binary, "--db", db.string(), "--listen",
                                     "127.0.0.1:" + std::to_string(grpc_port), "--udp-port",
                                     std::to_string(udp_port), "--ready-file", ready,
                                     // No palpation case built ahead: these tests run none, and
                                     // a case's table costs seconds of a core beside them.
                                     "--cases-ready", "0"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    const std::string log = (dir / "server.log").string();
    posix_spawn_file_actions_addopen(&actions, 2, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    const int rc = posix_spawn(&p.pid, argv[0], &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    EXPECT_EQ(rc, 0);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (std::chrono::steady_clock::now() < deadline) {
      std::ifstream in(ready);
      std::stringstream text;
      text << in.rdbuf();
      const auto j = nlohmann::json::parse(text.str(), nullptr, false);
      if (!j.is_discarded() && j.contains("grpc_port")) {
        p.grpc_port = j["grpc_port"].get<int>();
        p.udp_port = j.value("udp_port", 0);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    EXPECT_GT(p.grpc_port, 0) << "vsurg-server did not become ready (see " << log << ")";
    return p;
  }

  // Sends `sig` and reaps the process; returns its wait status.
  int Signal(int sig) {
    kill(pid, sig);
    int status = 0;
    waitpid(pid, &status, 0);
    pid = -1;
    return status;
  }

  // Freezes the process (SIGSTOP) or lets it go on (SIGCONT), without reaping it; 0 on success.
  int Freeze(bool frozen) { return kill(pid, frozen ? SIGSTOP : SIGCONT); }

  ServerProcess() = default;
  ServerProcess(ServerProcess&& o) noexcept
      : pid(o.pid), grpc_port(o.grpc_port), udp_port(o.udp_port) {
    o.pid = -1;
  }
  ServerProcess& operator=(ServerProcess&& o) noexcept {
    if (pid > 0) Signal(SIGKILL);
    pid = o.pid, grpc_port = o.grpc_port, udp_port = o.udp_port;
    o.pid = -1;
    return *this;
  }
  ~ServerProcess() {
    if (pid > 0) Signal(SIGKILL);
  }
};

struct ShellRun {
  int code = -1;
  std::string out;
};

// Runs a command line through the shell, capturing stdout.
inline ShellRun Shell(const std::string& command) {
  ShellRun r;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return r;
  char buf[4096];
  size_t n = 0;
  while ((n = fread(buf, 1, sizeof buf, pipe)) > 0) r.out.append(buf, n);
  const int status = pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace vsurg::test
