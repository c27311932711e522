#pragma once
// Test helpers: a loopback address of our own and the Aravis GigE Vision
// simulator (arv-fake-gv-camera-0.8) bound to it, both undone in every path
// by their destructors. The drivers tests use 127.0.1.x (other suites use
// other ranges), one address per test so parallel ctest runs do not collide.

#include <string>
#include <sys/types.h>

namespace lifmcr::test {

// `ip addr add ADDRESS/32 dev lo` unless it is already there; removed again
// by the destructor only if this object added it. Needs root.
class LoopbackAddress {
 public:
  explicit LoopbackAddress(std::string address);
  ~LoopbackAddress();
  LoopbackAddress(const LoopbackAddress&) = delete;
  LoopbackAddress& operator=(const LoopbackAddress&) = delete;
  bool ok() const { return ok_; }
  const std::string& address() const { return address_; }

 private:
  std::string address_;
  bool ok_ = false;
  bool added_ = false;
};

// One arv-fake-gv-camera-0.8 process; killed (SIGKILL) and reaped by Kill()
// and by the destructor.
class GvSimulator {
 public:
  GvSimulator(std::string address, std::string serial, int lost_packets_per_thousand = 0);
  ~GvSimulator();
  GvSimulator(const GvSimulator&) = delete;
  GvSimulator& operator=(const GvSimulator&) = delete;

  // Starts the process and waits until it answers GVCP discovery (a few
  // hundred ms). False when it did not start.
  bool Start();
  void Kill();
  bool running() const { return pid_ > 0; }

 private:
  std::string address_;
  std::string serial_;
  int lost_ratio_;
  pid_t pid_ = -1;
};

}  // namespace lifmcr::test
