#pragma once
// Runs the Node.js MAVLink peer (tests/mavlink_peer/peer.js) as a child process: stdin from /dev/null,
// stdout to a pipe this object reads line by line, stderr to the test's stderr. The destructor stops
// the child it started (by its pid) and reaps it.
#include <sys/types.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace vantage::test {

class PeerProcess {
 public:
  PeerProcess() = default;
  ~PeerProcess();
  PeerProcess(const PeerProcess&) = delete;
  PeerProcess& operator=(const PeerProcess&) = delete;

  // Starts the peer and waits for its "PORT <n>" line. Empty string on success, else why not.
  std::string start(const std::vector<std::string>& args);
  std::uint16_t port() const { return port_; }
  // The next stdout line; false on timeout or end of output.
  bool read_line(std::string* line, int timeout_ms);
  // Reads lines until one satisfies match (returned in *line); false on timeout or end of output.
  bool wait_for(const std::function<bool(const std::string&)>& match, int timeout_ms, std::string* line);
  // Lines read so far (for failure messages).
  const std::vector<std::string>& lines() const { return lines_; }

 private:
  pid_t pid_ = -1;
  int out_fd_ = -1;
  std::uint16_t port_ = 0;
  std::string pending_;
  std::vector<std::string> lines_;
};

// A number field of a JSON line written by the peer ("key":value); NaN when absent.
double json_number(const std::string& line, const std::string& key);
bool json_has(const std::string& line, const std::string& fragment);

}  // namespace vantage::test
