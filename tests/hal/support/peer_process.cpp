#include "tests/hal/support/peer_process.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>

#ifndef VANTAGE_NODE
#error "VANTAGE_NODE (path of node) must be defined by the build"
#endif
#ifndef VANTAGE_PEER_DIR
#error "VANTAGE_PEER_DIR must be defined by the build"
#endif

namespace vantage::test {

PeerProcess::~PeerProcess() {
  if (pid_ > 0) {
    ::kill(pid_, SIGTERM);
    int status = 0;
    ::waitpid(pid_, &status, 0);
  }
  if (out_fd_ >= 0) ::close(out_fd_);
}

std::string PeerProcess::start(const std::vector<std::string>& args) {
  const std::string dir = VANTAGE_PEER_DIR;
  const std::string script = dir + "/peer.js";
  if (::access((dir + "/node_modules/node-mavlink/package.json").c_str(), R_OK) != 0) {
    return "the MAVLink peer's npm packages are missing: run tests/mavlink_peer/install.sh";
  }
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC) != 0) return std::string("pipe: ") + std::strerror(errno);
  const pid_t pid = ::fork();
  if (pid < 0) return std::string("fork: ") + std::strerror(errno);
  if (pid == 0) {
    const int null_fd = ::open("/dev/null", O_RDONLY);
    ::dup2(null_fd, STDIN_FILENO);
    ::dup2(pipe_fds[1], STDOUT_FILENO);
    std::vector<char*> argv;
    std::string node = VANTAGE_NODE;
    argv.push_back(node.data());
    std::string script_copy = script;
    argv.push_back(script_copy.data());
    std::vector<std::string> copies(args);
    for (std::string& a : copies) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(node.c_str(), argv.data());
    _exit(127);
  }
  ::close(pipe_fds[1]);
  pid_ = pid;
  out_fd_ = pipe_fds[0];
  std::string line;
  if (!read_line(&line, 10000)) return "the peer printed no PORT line within 10 s";
  if (line.rfind("PORT ", 0) != 0) return "the peer's first line is not PORT <n>: " + line;
  port_ = static_cast<std::uint16_t>(std::atoi(line.c_str() + 5));
  if (port_ == 0) return "the peer printed a bad port: " + line;
  return {};
}

bool PeerProcess::read_line(std::string* line, int timeout_ms) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  for (;;) {
    const std::size_t newline = pending_.find('\n');
    if (newline != std::string::npos) {
      *line = pending_.substr(0, newline);
      pending_.erase(0, newline + 1);
      lines_.push_back(*line);
      return true;
    }
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0 || out_fd_ < 0) return false;
    pollfd pfd{out_fd_, POLLIN, 0};
    if (::poll(&pfd, 1, static_cast<int>(left)) <= 0) return false;
    char buffer[4096];
    const ssize_t n = ::read(out_fd_, buffer, sizeof buffer);
    if (n <= 0) return false;
    pending_.append(buffer, static_cast<std::size_t>(n));
  }
}

bool PeerProcess::wait_for(const std::function<bool(const std::string&)>& match, int timeout_ms, std::string* line) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0) return false;
    std::string candidate;
    if (!read_line(&candidate, static_cast<int>(left))) return false;
    if (match(candidate)) {
      if (line != nullptr) *line = candidate;
      return true;
    }
  }
}

double json_number(const std::string& line, const std::string& key) {
  const std::string needle = "\"" + key + "\":";
  const std::size_t at = line.find(needle);
  if (at == std::string::npos) return std::nan("");
  return std::strtod(line.c_str() + at + needle.size(), nullptr);
}

bool json_has(const std::string& line, const std::string& fragment) { return line.find(fragment) != std::string::npos; }

}  // namespace vantage::test
