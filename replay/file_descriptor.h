#pragma once
// A POSIX file descriptor closed on every path out; Close() closes early so
// a failing close (a delayed write error) can be reported. Shared by the BMP
// reader/writer and the recorder's O_DIRECT writer.

#include <unistd.h>

namespace lifmcr {

class FileDescriptor {
 public:
  explicit FileDescriptor(int fd) : fd_(fd) {}
  ~FileDescriptor() {
    if (fd_ >= 0) ::close(fd_);
  }
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  int get() const { return fd_; }
  int Close() {
    const int rc = ::close(fd_);
    fd_ = -1;
    return rc;
  }

 private:
  int fd_;
};

}  // namespace lifmcr
