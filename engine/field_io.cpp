#include "engine/field_io.hpp"

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include <fcntl.h>
#include <sys/statvfs.h>
#include <unistd.h>

namespace sandcell::io {

namespace {
// fsync of a file or directory by name. The rename is what makes the new file appear atomically;
// the syncs make sure that after a crash of the machine (not only of the process) the name never
// points at a file whose data had not reached the disk.
bool sync_path(const std::filesystem::path& p, bool directory) {
  const int fd = ::open(p.c_str(), directory ? (O_RDONLY | O_DIRECTORY) : O_RDONLY);
  if (fd < 0) return false;
  const bool ok = ::fsync(fd) == 0;
  ::close(fd);
  return ok;
}
}  // namespace

std::filesystem::path temporary_path(const std::filesystem::path& path) {
  std::filesystem::path tmp = path;
  tmp += ".tmp";
  return tmp;
}

void write_bytes(const std::filesystem::path& path, const std::vector<unsigned char>& bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw std::runtime_error(path.string() + ": cannot create the file (" + std::strerror(errno) + ")");
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string why = n < 0 ? std::strerror(errno) : "nothing written";
      ::close(fd);
      std::error_code ec;
      std::filesystem::remove(path, ec);
      throw std::runtime_error(path.string() + ": cannot write " + std::to_string(bytes.size()) + " bytes (" + why +
                               ")");
    }
    done += static_cast<std::size_t>(n);
  }
  if (::close(fd) != 0) {
    const std::string why = std::strerror(errno);
    std::error_code ec;
    std::filesystem::remove(path, ec);
    throw std::runtime_error(path.string() + ": cannot close the file (" + why + ")");
  }
}

void require_free_space(const std::filesystem::path& path, std::uint64_t bytes) {
  constexpr std::uint64_t k_reserve = 4u << 20;
  struct statvfs fs {};
  const std::filesystem::path where = std::filesystem::exists(path) ? path : path.parent_path();
  if (::statvfs(where.empty() ? "." : where.c_str(), &fs) != 0) return;  // unknown: let the write tell
  const std::uint64_t free = static_cast<std::uint64_t>(fs.f_bavail) * fs.f_frsize;
  if (free < bytes + k_reserve)
    throw std::runtime_error(path.string() + ": disk full: " + std::to_string(free >> 10) +
                             " KiB free on its file system, " + "writing needs about " +
                             std::to_string((bytes + k_reserve) >> 10) +
                             " KiB (with a 4 MiB reserve); the file is kept as of its last flush");
}

void commit_file(const std::filesystem::path& tmp, const std::filesystem::path& path) {
  std::error_code ec;
  if (!sync_path(tmp, false)) {
    const std::string why = std::strerror(errno);
    std::filesystem::remove(tmp, ec);
    throw std::runtime_error(path.string() + ": cannot sync " + tmp.string() + " (" + why + ")");
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw std::runtime_error(path.string() + ": cannot rename " + tmp.string() + " over it (" + ec.message() + ")");
  }
  // The file is in place; a failed directory sync only weakens durability, so it is not an error.
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  sync_path(dir, true);
}

}  // namespace sandcell::io
