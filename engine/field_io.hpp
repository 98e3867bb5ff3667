#pragma once
// Internal to the I/O layer (not installed): how the registry's array element types map onto HDF5
// datasets, and the write/read of one registry field. Checkpoints and results snapshots both use it,
// so a field type added to the registry needs one FieldLayout here and nothing else.
#include "components/fields.hpp"
#include "engine/hdf5.hpp"

#include <filesystem>
#include <string>
#include <vector>

namespace sandcell::io {

template <class T>
struct FieldLayout;  // no layout for this element type: add one
template <>
struct FieldLayout<double> {
  static constexpr h5::Scalar scalar = h5::Scalar::f64;
  static constexpr std::size_t width = 1;
};
template <>
struct FieldLayout<Vec3> {
  static constexpr h5::Scalar scalar = h5::Scalar::f64;
  static constexpr std::size_t width = 3;
};
template <>
struct FieldLayout<std::uint32_t> {
  static constexpr h5::Scalar scalar = h5::Scalar::u32;
  static constexpr std::size_t width = 1;
};
template <>
struct FieldLayout<Image> {
  static constexpr h5::Scalar scalar = h5::Scalar::i8;
  static constexpr std::size_t width = 3;
};
// Arrays are written straight from their storage: a Vec3 must be three packed doubles.
static_assert(sizeof(Vec3) == 3 * sizeof(double));
static_assert(sizeof(Image) == 3 * sizeof(std::int8_t));

/// Writes one registry array as dataset info.name, shape (n) or (n, width), with a `units` attribute.
template <class T>
void write_field(h5::Group& group, const FieldInfo& info, const std::vector<T>& values) {
  using L = FieldLayout<T>;
  const std::uint64_t shape[2] = {values.size(), L::width};
  h5::Dataset d = group.create_dataset(info.name, L::scalar, std::span(shape, L::width == 1 ? 1 : 2), values.data());
  d.set_string("units", info.units);
}

/// Reads one registry array of n entries, refusing a dataset of another shape or element type.
template <class T>
void read_field(const h5::Group& group, const FieldInfo& info, std::vector<T>& values, std::uint64_t n) {
  using L = FieldLayout<T>;
  const h5::Dataset d = group.open_dataset(info.name);
  const std::vector<std::uint64_t> shape = d.shape();
  const bool ok = L::width == 1 ? (shape.size() == 1 && shape[0] == n)
                                : (shape.size() == 2 && shape[0] == n && shape[1] == L::width);
  if (!ok) {
    // Built piecewise: GCC 12 warns falsely (-Wrestrict) on "(" + std::string(...) chains.
    std::string msg = "shape (";
    for (std::size_t k = 0; k < shape.size(); ++k) (msg += k ? "," : "") += std::to_string(shape[k]);
    msg += "), expected (";
    msg += std::to_string(n);
    if (L::width != 1) (msg += ",") += std::to_string(L::width);
    msg += ")";
    d.fail(msg);
  }
  values.resize(n);
  d.read(L::scalar, values.data(), n * L::width);
}

/// Writes `bytes` to `path` (created or truncated) with plain POSIX writes; a full disk (ENOSPC),
/// an I/O error or a permission problem is a std::runtime_error naming the file and the cause, and
/// leaves no partial file behind.
void write_bytes(const std::filesystem::path& path, const std::vector<unsigned char>& bytes);

/// Throws std::runtime_error "<path>: disk full ..." unless the file system holding `path` (or its
/// directory) has `bytes` plus a reserve of 4 MiB free. Checked before HDF5 writes a file in place:
/// HDF5 1.10 may crash closing a file whose write failed, and leave it unreadable.
void require_free_space(const std::filesystem::path& path, std::uint64_t bytes);

/// Makes a finished temporary file durable and puts it in place: fsync(tmp), rename(tmp, path),
/// fsync of the directory. Either path then holds the new file, or (on any failure, which throws
/// std::runtime_error) the old one is untouched; the temporary is removed on failure.
void commit_file(const std::filesystem::path& tmp, const std::filesystem::path& path);

/// "<path>.tmp": the name a file is written under before commit_file.
std::filesystem::path temporary_path(const std::filesystem::path& path);

}  // namespace sandcell::io
