#pragma once
// A small RAII layer over the HDF5 C API, for results files and checkpoints.
//
// hdf5.h stays out of this header (ids are carried as std::int64_t, the type of hid_t since HDF5
// 1.10), so a program that includes sandcell headers needs no HDF5 include path.
// Every failure throws std::runtime_error naming the file, the object path inside it and what was
// being done, with HDF5's own innermost message; HDF5's automatic printing of error stacks to stderr
// is switched off the first time a file is opened (a process-wide HDF5 setting).
// The serial HDF5 library is not thread-safe: use these types from one thread at a time.
//
// Element types are stored in the file as little-endian IEEE doubles and two's-complement integers
// of the named width, and read back only from exactly that stored type, so a value comes back bit
// for bit (no silent conversion of a float file into integers or of int64 into int8).
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace sandcell::h5 {

using Hid = std::int64_t;  // hid_t

/// Element types the I/O layer stores.
enum class Scalar : std::uint8_t { f64, i8, u32, i64, u64 };

template <class T>
constexpr Scalar scalar_of() {
  if constexpr (std::is_same_v<T, double>)
    return Scalar::f64;
  else if constexpr (std::is_same_v<T, std::int8_t>)
    return Scalar::i8;
  else if constexpr (std::is_same_v<T, std::uint32_t>)
    return Scalar::u32;
  else if constexpr (std::is_same_v<T, std::int64_t>)
    return Scalar::i64;
  else if constexpr (std::is_same_v<T, std::uint64_t>)
    return Scalar::u64;
  else
    static_assert(!sizeof(T), "no HDF5 element type for this C++ type");
}

/// Owns one HDF5 id (file, group, dataset, dataspace, type, property list, attribute) and releases
/// it on destruction. Move-only.
class Handle {
 public:
  Handle() = default;
  explicit Handle(Hid id) : id_(id) {}
  Handle(Handle&& other) noexcept : id_(other.id_) { other.id_ = -1; }
  Handle& operator=(Handle&& other) noexcept;
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { reset(); }

  Hid get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  /// Releases the id if it is still valid in HDF5.
  void reset() noexcept;
  /// Forgets the id without releasing it (after it was closed by other means).
  void release() noexcept { id_ = -1; }

 private:
  Hid id_ = -1;
};

class Dataset;

/// A group or a dataset: an object that carries attributes. Knows its file and path for messages.
class Node {
 public:
  Hid id() const { return handle_.get(); }
  const std::string& file_path() const { return file_; }
  const std::string& object_path() const { return path_; }

  bool has_attribute(std::string_view name) const;
  /// Names of this object's attributes, in increasing name order.
  std::vector<std::string> attribute_names() const;
  void remove_attribute(std::string_view name);
  /// Writes (or replaces) a text attribute, stored as a fixed-length UTF-8 string.
  void set_string(std::string_view name, std::string_view text);
  /// Reads a text attribute (fixed- or variable-length string).
  std::string get_string(std::string_view name) const;
  /// Writes (or replaces) a scalar attribute.
  template <class T>
  void set_value(std::string_view name, T value) {
    write_attribute(name, scalar_of<T>(), &value, 1, true);
  }
  /// Writes (or replaces) a 1-d array attribute.
  template <class T>
  void set_values(std::string_view name, std::span<const T> values) {
    write_attribute(name, scalar_of<T>(), values.data(), values.size(), false);
  }
  /// Reads an attribute holding exactly one element of type T.
  template <class T>
  T get_value(std::string_view name) const {
    T v{};
    read_attribute(name, scalar_of<T>(), &v, 1, true);
    return v;
  }
  /// Reads an attribute of elements of type T, any length.
  template <class T>
  std::vector<T> get_values(std::string_view name) const {
    std::vector<T> v(attribute_size(name));
    read_attribute(name, scalar_of<T>(), v.data(), v.size(), false);
    return v;
  }

  /// Throws std::runtime_error "<file>: <object>: <what>", with HDF5's innermost message if any.
  [[noreturn]] void fail(std::string_view what) const;

  /// Forgets the object without closing it: after a failed write (a full disk) HDF5 may crash
  /// closing objects of that file, so they are left to the process's exit.
  void abandon() noexcept { handle_.release(); }

 protected:
  Node() = default;
  Node(Handle handle, std::string file, std::string path)
      : handle_(std::move(handle)), file_(std::move(file)), path_(std::move(path)) {}
  std::string child_path(std::string_view name) const;

 private:
  void write_attribute(std::string_view name, Scalar type, const void* data, std::size_t count, bool scalar);
  void read_attribute(std::string_view name, Scalar type, void* data, std::size_t count, bool scalar) const;
  std::size_t attribute_size(std::string_view name) const;

  Handle handle_;
  std::string file_;
  std::string path_;
};

/// A dataset of one of the Scalar element types.
class Dataset : public Node {
 public:
  Dataset() = default;
  /// Extent per dimension.
  std::vector<std::uint64_t> shape() const;
  /// Whether the stored element type is exactly `type`.
  bool stores(Scalar type) const;
  /// Reads every element into out[0, count); count must equal the number of elements and the
  /// stored type must be `type`.
  void read(Scalar type, void* out, std::size_t count) const;
  template <class T>
  std::vector<T> read() const {
    std::size_t n = 1;
    for (std::uint64_t d : shape()) n *= d;
    std::vector<T> v(n);
    read(scalar_of<T>(), v.data(), n);
    return v;
  }
  /// For a dataset of shape (rows, width) or (rows) with an unlimited first dimension: appends
  /// one row of `width` elements.
  void append_row(Scalar type, const void* row, std::size_t width);
  /// Cuts an extendible dataset back (or grows it) to `rows` rows.
  void set_rows(std::uint64_t rows);

 private:
  friend class Group;
  using Node::Node;
};

/// A group (the file's root is one).
class Group : public Node {
 public:
  Group() = default;
  /// Whether a link (group or dataset) of that name exists here.
  bool has(std::string_view name) const;
  /// Names of the links in this group, in increasing name order.
  std::vector<std::string> children() const;
  Group open_group(std::string_view name) const;
  Group create_group(std::string_view name);
  /// Opens the group, creating it (and missing parents in a path "a/b/c") if needed.
  Group require_group(std::string_view name);
  /// Unlinks a child (its space in the file is not reclaimed: HDF5 does not compact files).
  void remove(std::string_view name);

  Dataset open_dataset(std::string_view name) const;
  /// Creates a fixed-size dataset of the given shape and writes data (product of shape elements).
  Dataset create_dataset(std::string_view name, Scalar type, std::span<const std::uint64_t> shape, const void* data);
  template <class T>
  Dataset create_dataset(std::string_view name, std::span<const T> data, std::span<const std::uint64_t> shape) {
    std::uint64_t n = 1;
    for (std::uint64_t d : shape) n *= d;
    if (n != data.size()) fail("dataset '" + std::string(name) + "': shape does not match the data size");
    return create_dataset(name, scalar_of<T>(), shape, data.data());
  }
  /// Creates an empty, chunked dataset with an unlimited first dimension: shape (0, width), or
  /// (0) when width is 1, for row-by-row appends.
  Dataset create_extendible(std::string_view name, Scalar type, std::uint64_t width);

 private:
  friend class File;
  using Node::Node;
};

/// An open HDF5 file. Move-only; the destructor closes it (errors then are swallowed: call close()
/// to see them). Groups and datasets opened from it keep it alive in HDF5 until they are closed,
/// and close() refuses (throws) while any is still open, so a file is never left half-closed.
class File {
 public:
  enum class Mode { read, read_write };
  /// Creates (truncates) a file. `userblock`: bytes reserved at its start that HDF5 neither writes
  /// nor reads (0, or a power of two >= 512), for the caller's own header.
  static File create(const std::filesystem::path& path, std::size_t userblock = 0);
  /// Creates a file in memory only (HDF5's core driver, no backing store); image() returns its bytes.
  /// `path` names it in messages.
  static File create_in_memory(const std::filesystem::path& path);
  /// Opens an existing file; throws if it is missing or not an HDF5 file.
  static File open(const std::filesystem::path& path, Mode mode);

  File(File&&) noexcept = default;
  File& operator=(File&& other) noexcept;
  File(const File&) = delete;
  File& operator=(const File&) = delete;
  ~File();

  const std::filesystem::path& path() const { return path_; }
  bool is_open() const { return handle_.valid(); }
  Group root() const;
  /// Flushes the whole file to the operating system (H5Fflush, global scope).
  void flush();
  /// Closes the file; throws if HDF5 reports an error (e.g. objects still open).
  void close();
  /// The bytes of the whole file as it would be on disk (flushes first). For files in memory.
  std::vector<unsigned char> image();
  /// Forgets the file without closing it (see Node::abandon): what was flushed stays on disk.
  void abandon() noexcept { handle_.release(); }

 private:
  File(Handle handle, std::filesystem::path path) : handle_(std::move(handle)), path_(std::move(path)) {}
  Handle handle_;
  std::filesystem::path path_;
};

}  // namespace sandcell::h5
