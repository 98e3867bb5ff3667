#include "engine/field_io.hpp"

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include <fcntl.h>
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
