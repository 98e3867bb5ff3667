#pragma once
// The results file of a run (docs/physics.md section 8), and its XDMF sidecar for ParaView.
//
// Layout (schema version k_results_schema):
//   /                       attributes format = "sandcell results", schema_version, software_version,
//                           config (the full config text), plus any caller attributes (strings)
//   /series/<name>          extendible float64 datasets, one row per sample: shape (rows) for a
//                           scalar series, (rows, width) otherwise; attribute `units`. All series of
//                           a run are sampled together with /series/step, which reopen() uses.
//   /snapshots/<step>/      step zero-padded to 12 digits; particle arrays position, velocity,
//                           angular_velocity, force (n,3), radius (n), id (n, uint32), each with
//                           `units`; attributes step, time (s), cell_length (3 doubles, m)
// Other groups (e.g. one per test of a campaign) may be added with set_attribute().
//
// Crash behaviour: create() and flush() push everything written so far to the operating system, so
// a killed run leaves a file readable up to its last flush; before a flush or a snapshot the free
// space is checked (io::require_free_space), and a write that fails anyway (a full disk, an I/O
// error) drops the file's handles unclosed, leaving the file as of its last flush; a run resumed from a checkpoint reopen()s the
// file and cuts it back to the checkpoint's step, so no sample is duplicated.
#include "engine/state.hpp"

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace sandcell {

/// Bumped whenever the results layout changes.
inline constexpr std::int64_t k_results_schema = 1;

class ResultsFile {
 public:
  /// Creates path (truncating) with attributes: config text, software version, schema version, plus any attrs.
  static ResultsFile create(const std::filesystem::path& path, std::string_view config_text,
                            const std::map<std::string, std::string>& attributes = {});
  /// Reopens an existing results file to continue a resumed run: every /series dataset is cut back to
  /// the rows whose `step` value is <= last_step, and snapshots with step > last_step are removed.
  /// A series appended later that the file lacks (one a newer build writes) gets NaN in the kept
  /// rows, so every series stays row-aligned with /series/step.
  /// Throws std::runtime_error if the file is missing, not a results file of this schema version,
  /// or has series but no /series/step to cut them by.
  static ResultsFile reopen(const std::filesystem::path& path, std::uint64_t last_step);
  /// As reopen(path, last_step), with the series cut after last_row_step and the snapshots after
  /// last_snapshot_step (a finished test continued to a larger strain drops the row and snapshot
  /// written only because it ended there).
  static ResultsFile reopen(const std::filesystem::path& path, std::uint64_t last_row_step,
                            std::uint64_t last_snapshot_step);

  ResultsFile(ResultsFile&&) noexcept;
  ResultsFile& operator=(ResultsFile&&) noexcept;
  ResultsFile(const ResultsFile&) = delete;
  ResultsFile& operator=(const ResultsFile&) = delete;
  /// Closes (as close(), errors swallowed).
  ~ResultsFile();

  /// Appends one row to the extendible dataset /series/<name> (created on first use with width = values.size(),
  /// chunked, shape (rows, width), or (rows) when width 1), with a `units` attribute.
  /// A row of another width, or other units than the series was created with, is std::invalid_argument.
  void append(std::string_view name, std::span<const double> values, std::string_view units);
  void append(std::string_view name, double value, std::string_view units);

  /// Writes /snapshots/<step zero-padded to 12 digits>/ with position, velocity, angular_velocity, radius, id,
  /// force (and the cell lengths and time as attributes). A snapshot of the same step is replaced.
  void write_snapshot(const State& state);

  /// Sets an attribute on a group ("/" for the root, "tests/b0.25" creates missing groups).
  void set_attribute(std::string_view group, std::string_view name, std::string_view value);
  void set_attribute(std::string_view group, std::string_view name, double value);
  /// Removes an attribute of a group ("/" for the root) if it is there.
  void remove_attribute(std::string_view group, std::string_view name);

  /// H5Fflush: a killed run leaves a readable file up to here.
  void flush();
  /// Closes the file, then writes the XDMF sidecar (write_xdmf). Idempotent.
  void close();

  const std::filesystem::path& path() const;
  bool is_open() const;

 private:
  // Runs fn; on a failure other than a caller's mistake (std::invalid_argument), drops the file's
  // handles unclosed and rethrows: the file on disk stays as of its last flush.
  template <class Fn>
  void guarded(Fn&& fn);
  void write_snapshot_unguarded(const State& state);

  struct Impl;
  explicit ResultsFile(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Where the XDMF sidecar of a results file goes: the same name with extension ".xdmf"
/// (run.h5 -> run.xdmf).
std::filesystem::path xdmf_path(const std::filesystem::path& results_path);

/// Writes the XDMF 3 sidecar of a results file: a temporal collection of Polyvertex grids, one per
/// snapshot, whose geometry and attributes point into the HDF5 file (by its file name, so the two
/// files move together). Written atomically; returns its path.
std::filesystem::path write_xdmf(const std::filesystem::path& results_path);

}  // namespace sandcell
