#include "lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace sandcell::triaxial {

int FileLock::open_file(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) throw std::runtime_error(path.string() + ": cannot open the lock file: " + std::strerror(errno));
  return fd;
}

void FileLock::note_holder() {
  char host[256] = "?";
  ::gethostname(host, sizeof host - 1);
  const std::string text = "PID " + std::to_string(::getpid()) + " on " + host + "\n";
  // Written over the last holder's note, then cut to length, so that a reader never finds it empty.
  if (::pwrite(fd_, text.data(), text.size(), 0) < 0 || ::ftruncate(fd_, static_cast<off_t>(text.size())) != 0) {
    // The note is for messages only; a lock without it still protects.
  }
}

bool FileLock::try_lock(const std::filesystem::path& path, Mode mode) {
  unlock();
  const int fd = open_file(path);
  while (::flock(fd, (mode == Mode::exclusive ? LOCK_EX : LOCK_SH) | LOCK_NB) != 0) {
    if (errno == EINTR) continue;
    ::close(fd);
    return false;
  }
  fd_ = fd;
  note_holder();
  return true;
}

void FileLock::lock(const std::filesystem::path& path, Mode mode) {
  unlock();
  const int fd = open_file(path);
  while (::flock(fd, mode == Mode::exclusive ? LOCK_EX : LOCK_SH) != 0) {
    if (errno == EINTR) continue;
    const int e = errno;
    ::close(fd);
    throw std::runtime_error(path.string() + ": cannot lock: " + std::strerror(e));
  }
  fd_ = fd;
  note_holder();
}

void FileLock::unlock() {
  if (fd_ < 0) return;
  ::flock(fd_, LOCK_UN);
  ::close(fd_);
  fd_ = -1;
}

FileLock& FileLock::operator=(FileLock&& o) noexcept {
  if (this != &o) {
    unlock();
    fd_ = o.fd_;
    o.fd_ = -1;
  }
  return *this;
}

std::string FileLock::holder(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line.empty() ? "another process" : line;
}

}  // namespace sandcell::triaxial
