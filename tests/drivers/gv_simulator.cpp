#include "tests/drivers/gv_simulator.h"

#include <arpa/inet.h>
#include <chrono>
#include <cstdlib>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>


namespace lifmcr::test {
namespace {

int RunQuiet(const std::string& command) {
  return std::system((command + " >/dev/null 2>&1").c_str());
}

// Sends a GVCP READREG of the Version register (0x0) to address:3956 and
// waits up to 100 ms for any answer.
bool AnswersGvcp(const std::string& address) {
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  if (fd < 0) return false;
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(3956);
  inet_pton(AF_INET, address.c_str(), &to.sin_addr);
  // GVCP header: 0x42, flags 0x01 (ack required), command 0x0080 READREG,
  // length 4, request id 1; then the register address 0.
  const unsigned char packet[] = {0x42, 0x01, 0x00, 0x80, 0x00, 0x04,
                                  0x00, 0x01, 0x00, 0x00, 0x00, 0x00};
  timeval timeout{0, 100000};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
  bool answered = false;
  if (sendto(fd, packet, sizeof(packet), 0, reinterpret_cast<sockaddr*>(&to), sizeof(to)) ==
      static_cast<ssize_t>(sizeof(packet))) {
    unsigned char reply[64];
    answered = recv(fd, reply, sizeof(reply), 0) > 0;
  }
  close(fd);
  return answered;
}

}  // namespace

std::string ProcessLoopbackAddress(int slot) {
  // 254 host numbers per third octet, never .0 or .255.
  const auto pid = static_cast<unsigned>(getpid());
  return "127." + std::to_string(100 + slot) + "." + std::to_string((pid / 254) % 256) + "." +
         std::to_string(1 + pid % 254);
}

LoopbackAddress::LoopbackAddress(std::string address) : address_(std::move(address)) {
  const bool present =
      RunQuiet("ip -4 addr show dev lo | grep -qw 'inet " + address_ + "/32'") == 0;
  if (present) {
    ok_ = true;
    return;
  }
  added_ = RunQuiet("ip addr add " + address_ + "/32 dev lo") == 0;
  ok_ = added_;
}

LoopbackAddress::~LoopbackAddress() {
  if (added_) RunQuiet("ip addr del " + address_ + "/32 dev lo");
}

GvSimulator::GvSimulator(std::string address, std::string serial, int lost_packets_per_thousand)
    : address_(std::move(address)),
      serial_(std::move(serial)),
      lost_ratio_(lost_packets_per_thousand) {}

GvSimulator::~GvSimulator() { Kill(); }

bool GvSimulator::Start() {
  if (pid_ > 0) return true;
  std::vector<std::string> args = {"arv-fake-gv-camera-0.8", "-i", address_, "-s", serial_};
  if (lost_ratio_ > 0) {
    args.push_back("-r");
    args.push_back(std::to_string(lost_ratio_));
  }
  std::vector<char*> argv;
  for (std::string& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);
  // fork + exec rather than posix_spawn: the simulator is killed with the
  // test (PR_SET_PDEATHSIG) when the test dies without its destructors (a
  // sanitizer halting it, a crash, ctest's timeout), so no stale simulator
  // answers the next run on the same address. Only async-signal-safe calls
  // before exec.
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) return false;
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);  // the test died before prctl
    const int null = open("/dev/null", O_WRONLY);
    if (null >= 0) {
      dup2(null, 1);
      dup2(null, 2);
    }
    execvp(argv[0], argv.data());
    _exit(127);
  }
  pid_ = pid;
  for (int i = 0; i < 50; ++i) {
    if (AnswersGvcp(address_)) return true;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {  // exited: address missing?
      pid_ = -1;
      return false;
    }
  }
  Kill();
  return false;
}

void GvSimulator::Kill() {
  if (pid_ <= 0) return;
  kill(pid_, SIGKILL);
  int status = 0;
  waitpid(pid_, &status, 0);
  pid_ = -1;
}

}  // namespace lifmcr::test
