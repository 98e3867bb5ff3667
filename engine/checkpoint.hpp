#pragma once
// Checkpoints: the whole State in one HDF5 file, so a run continues bit for bit from it.
//
// Layout (schema version k_checkpoint_schema):
//   /                 attributes format = "sandcell checkpoint", schema_version, software_version
//   /particles/<f>    every particle array of the field registry, (n) or (n,3), attribute `units`
//   /contacts/<f>     every allocated contact array of the registry, (m) or (m,3); attributes
//                     has_rolling (0/1) and reference_length (3 doubles, m)
//   /cell             attributes length, length0 (m), rate (1/s), 3 doubles each
//   /clock            attributes step (uint64), time (s), dt (s: only under an adaptive step)
//   /extra/doubles/<key>, /extra/integers/<key>   1-d datasets;  /extra/strings: one attribute per key
// Arrays are walked through the registry (components/fields.hpp), so a new field is saved and
// restored without touching this file.
#include "engine/state.hpp"

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace sandcell {

/// Bumped whenever the checkpoint layout changes; read_checkpoint refuses any other version.
inline constexpr std::int64_t k_checkpoint_schema = 1;

/// Application state saved beside the engine State (stage index, servo/stop-criterion memory...).
/// Keys of `doubles` and `integers` name datasets: non-empty, without '/', not ".".
struct CheckpointExtra {
  std::map<std::string, std::vector<double>> doubles;
  std::map<std::string, std::vector<std::int64_t>> integers;
  std::map<std::string, std::string> strings;
};

/// Writes the whole State (every particle and contact field via the registry, contacts.has_rolling,
/// contacts.pairs.reference_length, cell length/length0/rate, clock step/time) plus extra, atomically:
/// to "<path>.tmp", flushed, synced and closed, then renamed over path. A failure leaves an existing
/// file at path untouched (and removes the temporary) and throws std::runtime_error naming path;
/// a State whose arrays disagree in length, or a bad extra key, throws std::invalid_argument.
void write_checkpoint(const std::filesystem::path& path, const State& state, const CheckpointExtra& extra = {});

/// Reads it back bitwise (doubles stored as IEEE doubles, ids uint32, image as int8 (m,3), material uint32).
/// Throws std::runtime_error naming the path and what is missing/wrong (including schema version mismatch).
State read_checkpoint(const std::filesystem::path& path, CheckpointExtra* extra = nullptr);

}  // namespace sandcell
