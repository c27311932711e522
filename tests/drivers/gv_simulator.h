#pragma once
// Test helpers: a loopback address of our own and the Aravis GigE Vision
// simulator (arv-fake-gv-camera-0.8) bound to it, both undone in every path
// by their destructors. Addresses come from ProcessLoopbackAddress, so no
// two test processes on the host share one: not within one `ctest -j` run,
// nor across runs at once (another worktree's suite, a sanitizer build's),
// where fixed addresses made the second simulator fail to bind GVCP (3956)
// and its test time out on register writes.

#include <string>
#include <sys/types.h>

namespace lifmcr::test {

// 127.<100 + slot>.X.Y with X.Y from this process's id (slot 0..99: the
// test's own addresses, several per test where it needs them).
std::string ProcessLoopbackAddress(int slot);

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
