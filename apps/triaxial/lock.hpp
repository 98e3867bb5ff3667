#pragma once
// Advisory locks in the output directory (flock(2); on NFS the Linux client maps them to the
// server's byte-range locks), held for the life of what they protect and released by the kernel
// when the process dies, so a killed run never leaves a stale lock:
//   .sandcell.lock        the directory: exclusive for a whole run (or --overwrite), shared for a
//                         run of selected tasks (--task), so array tasks work side by side while a
//                         second whole run, or an --overwrite, is refused;
//   .locks/<job>.lock     one job (a preparation or a test): exclusive while it runs, so the same
//                         task never runs twice at once;
//   .locks/index.csv.lock the merge of index.csv and samples.csv.
// A lock file holds the PID and host of its latest holder, for the error message.
#include <filesystem>
#include <string>

namespace sandcell::triaxial {

class FileLock {
 public:
  enum class Mode { shared, exclusive };
  FileLock() = default;
  /// Takes the lock without waiting; false (and nothing held) when another process holds it.
  /// Throws std::runtime_error when the lock file cannot be opened.
  bool try_lock(const std::filesystem::path& path, Mode mode);
  /// Takes the lock, waiting for the holder to release it.
  void lock(const std::filesystem::path& path, Mode mode);
  void unlock();
  ~FileLock() { unlock(); }
  FileLock(FileLock&& o) noexcept : fd_(o.fd_) { o.fd_ = -1; }
  FileLock& operator=(FileLock&& o) noexcept;
  FileLock(const FileLock&) = delete;
  FileLock& operator=(const FileLock&) = delete;
  bool held() const { return fd_ >= 0; }

  /// "PID 1234 on host", as written by the latest holder of `path` ("another process" if none).
  static std::string holder(const std::filesystem::path& path);

 private:
  int fd_ = -1;
  int open_file(const std::filesystem::path& path);
  void note_holder();
};

}  // namespace sandcell::triaxial
