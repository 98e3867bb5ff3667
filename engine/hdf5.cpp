#include "engine/hdf5.hpp"

#include <hdf5.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>

namespace sandcell::h5 {

static_assert(std::is_same_v<hid_t, Hid>, "Hid must be hid_t (HDF5 >= 1.10)");
static_assert(sizeof(hsize_t) == sizeof(std::uint64_t), "shapes are passed as uint64");

namespace {

// HDF5 prints its error stack to stderr by default; we report through exceptions instead.
void silence_hdf5() {
  static const bool done = [] {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    return true;
  }();
  (void)done;
}

// The innermost (first) message of HDF5's current error stack, then clears it.
std::string hdf5_detail() {
  std::string detail;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_DOWNWARD,
      [](unsigned n, const H5E_error2_t* e, void* out) -> herr_t {
        if (n == 0 && e != nullptr) {
          auto& s = *static_cast<std::string*>(out);
          s = std::string(e->func_name ? e->func_name : "?") + ": " + (e->desc ? e->desc : "");
        }
        return 0;
      },
      &detail);
  H5Eclear2(H5E_DEFAULT);
  return detail;
}

[[noreturn]] void throw_error(const std::string& file, const std::string& object, std::string_view what) {
  std::string msg = "HDF5 file " + file;
  if (!object.empty()) msg += ", object " + object;
  msg += ": ";
  msg += what;
  const std::string detail = hdf5_detail();
  if (!detail.empty()) msg += " (" + detail + ")";
  throw std::runtime_error(msg);
}

// The type stored in the file: fixed byte order, so files are the same on every machine.
hid_t file_type(Scalar s) {
  switch (s) {
    case Scalar::f64: return H5T_IEEE_F64LE;
    case Scalar::i8: return H5T_STD_I8LE;
    case Scalar::u32: return H5T_STD_U32LE;
    case Scalar::i64: return H5T_STD_I64LE;
    case Scalar::u64: return H5T_STD_U64LE;
  }
  return H5T_IEEE_F64LE;
}

hid_t memory_type(Scalar s) {
  switch (s) {
    case Scalar::f64: return H5T_NATIVE_DOUBLE;
    case Scalar::i8: return H5T_NATIVE_INT8;
    case Scalar::u32: return H5T_NATIVE_UINT32;
    case Scalar::i64: return H5T_NATIVE_INT64;
    case Scalar::u64: return H5T_NATIVE_UINT64;
  }
  return H5T_NATIVE_DOUBLE;
}

const char* scalar_name(Scalar s) {
  switch (s) {
    case Scalar::f64: return "float64";
    case Scalar::i8: return "int8";
    case Scalar::u32: return "uint32";
    case Scalar::i64: return "int64";
    case Scalar::u64: return "uint64";
  }
  return "?";
}

// Appended piecewise: GCC 12 warns falsely (-Wrestrict) on "'" + std::string(...) + "'".
std::string quoted(std::string_view name) {
  std::string s(1, '\'');
  s += name;
  s += '\'';
  return s;
}

std::uint64_t element_count(hid_t space) {
  const hssize_t n = H5Sget_simple_extent_npoints(space);
  return n < 0 ? 0 : static_cast<std::uint64_t>(n);
}

}  // namespace

// ---- Handle -------------------------------------------------------------------------------------

Handle& Handle::operator=(Handle&& other) noexcept {
  if (this != &other) {
    reset();
    id_ = other.id_;
    other.id_ = -1;
  }
  return *this;
}

void Handle::reset() noexcept {
  // H5Idec_ref closes any kind of id when its count drops to zero.
  if (id_ >= 0 && H5Iis_valid(id_) > 0) H5Idec_ref(id_);
  id_ = -1;
}

// ---- Node (attributes) ------------------------------------------------------------------------

void Node::fail(std::string_view what) const { throw_error(file_, path_, what); }

std::string Node::child_path(std::string_view name) const {
  std::string s = path_;
  if (s.empty() || s.back() != '/') s += '/';
  s += name;
  return s;
}

bool Node::has_attribute(std::string_view name) const {
  const std::string n(name);
  const htri_t r = H5Aexists(id(), n.c_str());
  if (r < 0) fail("cannot query attribute " + quoted(name));
  return r > 0;
}

std::vector<std::string> Node::attribute_names() const {
  std::vector<std::string> names;
  hsize_t index = 0;
  const herr_t r = H5Aiterate2(
      id(), H5_INDEX_NAME, H5_ITER_INC, &index,
      [](hid_t, const char* name, const H5A_info_t*, void* out) -> herr_t {
        static_cast<std::vector<std::string>*>(out)->emplace_back(name);
        return 0;
      },
      &names);
  if (r < 0) fail("cannot list the attributes");
  return names;
}

void Node::remove_attribute(std::string_view name) {
  const std::string n(name);
  if (H5Adelete(id(), n.c_str()) < 0) fail("cannot delete attribute " + quoted(name));
}

void Node::set_string(std::string_view name, std::string_view text) {
  if (has_attribute(name)) remove_attribute(name);
  // HDF5 refuses zero-sized string types: an empty text is one NUL byte, null-padded.
  Handle type(H5Tcopy(H5T_C_S1));
  if (!type.valid() || H5Tset_size(type.get(), std::max<std::size_t>(text.size(), 1)) < 0 ||
      H5Tset_strpad(type.get(), H5T_STR_NULLPAD) < 0 || H5Tset_cset(type.get(), H5T_CSET_UTF8) < 0)
    fail("cannot make a string type for attribute " + quoted(name));
  Handle space(H5Screate(H5S_SCALAR));
  const std::string n(name);
  Handle attr(H5Acreate2(id(), n.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT));
  if (!attr.valid()) fail("cannot create attribute " + quoted(name));
  std::string buffer(text);
  if (buffer.empty()) buffer.push_back('\0');
  if (H5Awrite(attr.get(), type.get(), buffer.data()) < 0) fail("cannot write attribute " + quoted(name));
}

std::string Node::get_string(std::string_view name) const {
  const std::string n(name);
  Handle attr(H5Aopen(id(), n.c_str(), H5P_DEFAULT));
  if (!attr.valid()) fail("missing attribute " + quoted(name));
  Handle type(H5Aget_type(attr.get()));
  if (H5Tget_class(type.get()) != H5T_STRING) fail("attribute " + quoted(name) + " is not a string");
  Handle space(H5Aget_space(attr.get()));
  if (element_count(space.get()) != 1) fail("attribute " + quoted(name) + " is not a single string");
  if (H5Tis_variable_str(type.get()) > 0) {
    // Written by other tools (h5py's default): HDF5 allocates the text, we free it.
    Handle mem(H5Tcopy(H5T_C_S1));
    H5Tset_size(mem.get(), H5T_VARIABLE);
    H5Tset_cset(mem.get(), H5Tget_cset(type.get()));
    char* text = nullptr;
    if (H5Aread(attr.get(), mem.get(), &text) < 0) fail("cannot read attribute " + quoted(name));
    std::string out = text ? text : "";
    H5free_memory(text);
    return out;
  }
  std::string out(H5Tget_size(type.get()), '\0');
  if (H5Aread(attr.get(), type.get(), out.data()) < 0) fail("cannot read attribute " + quoted(name));
  // Null padding (and a C terminator, from other writers) is not part of the text.
  out.resize(std::strlen(out.c_str()));
  return out;
}

void Node::write_attribute(std::string_view name, Scalar type, const void* data, std::size_t count, bool scalar) {
  if (has_attribute(name)) remove_attribute(name);
  const hsize_t dims[1] = {count};
  Handle space(scalar ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, dims, nullptr));
  const std::string n(name);
  Handle attr(H5Acreate2(id(), n.c_str(), file_type(type), space.get(), H5P_DEFAULT, H5P_DEFAULT));
  if (!attr.valid()) fail("cannot create attribute " + quoted(name));
  if (count > 0 && H5Awrite(attr.get(), memory_type(type), data) < 0) fail("cannot write attribute " + quoted(name));
}

std::size_t Node::attribute_size(std::string_view name) const {
  const std::string n(name);
  Handle attr(H5Aopen(id(), n.c_str(), H5P_DEFAULT));
  if (!attr.valid()) fail("missing attribute " + quoted(name));
  Handle space(H5Aget_space(attr.get()));
  return element_count(space.get());
}

void Node::read_attribute(std::string_view name, Scalar type, void* data, std::size_t count, bool scalar) const {
  const std::string n(name);
  Handle attr(H5Aopen(id(), n.c_str(), H5P_DEFAULT));
  if (!attr.valid()) fail("missing attribute " + quoted(name));
  Handle stored(H5Aget_type(attr.get()));
  if (H5Tequal(stored.get(), file_type(type)) <= 0)
    fail("attribute " + quoted(name) + " is not of type " + scalar_name(type));
  Handle space(H5Aget_space(attr.get()));
  const std::uint64_t n_stored = element_count(space.get());
  if (n_stored != count)
    fail("attribute " + quoted(name) + " holds " + std::to_string(n_stored) + " values, expected " +
         (scalar ? std::string("one") : std::to_string(count)));
  if (count > 0 && H5Aread(attr.get(), memory_type(type), data) < 0) fail("cannot read attribute " + quoted(name));
}

// ---- Dataset ------------------------------------------------------------------------------------

std::vector<std::uint64_t> Dataset::shape() const {
  Handle space(H5Dget_space(id()));
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 0) fail("cannot read the shape");
  std::vector<std::uint64_t> dims(static_cast<std::size_t>(rank));
  if (rank > 0) H5Sget_simple_extent_dims(space.get(), reinterpret_cast<hsize_t*>(dims.data()), nullptr);
  return dims;
}

bool Dataset::stores(Scalar type) const {
  Handle stored(H5Dget_type(id()));
  return H5Tequal(stored.get(), file_type(type)) > 0;
}

void Dataset::read(Scalar type, void* out, std::size_t count) const {
  if (!stores(type)) fail(std::string("the stored element type is not ") + scalar_name(type));
  Handle space(H5Dget_space(id()));
  const std::uint64_t n = element_count(space.get());
  if (n != count) fail("holds " + std::to_string(n) + " values, expected " + std::to_string(count));
  if (count > 0 && H5Dread(id(), memory_type(type), H5S_ALL, H5S_ALL, H5P_DEFAULT, out) < 0) fail("cannot read");
}

void Dataset::append_row(Scalar type, const void* row, std::size_t width) {
  std::vector<std::uint64_t> dims = shape();
  const std::uint64_t stored_width = dims.size() == 2 ? dims[1] : 1;
  if (dims.empty() || dims.size() > 2 || stored_width != width)
    fail("cannot append a row of " + std::to_string(width) + " values to a dataset of width " +
         std::to_string(stored_width));
  ++dims[0];
  if (H5Dset_extent(id(), reinterpret_cast<const hsize_t*>(dims.data())) < 0) fail("cannot extend");
  Handle file_space(H5Dget_space(id()));
  const hsize_t start[2] = {dims[0] - 1, 0};
  const hsize_t count[2] = {1, width};
  if (H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr) < 0)
    fail("cannot select the new row");
  const hsize_t mem_dims[1] = {width};
  Handle mem_space(H5Screate_simple(1, mem_dims, nullptr));
  if (H5Dwrite(id(), memory_type(type), mem_space.get(), file_space.get(), H5P_DEFAULT, row) < 0)
    fail("cannot write a row");
}

void Dataset::set_rows(std::uint64_t rows) {
  std::vector<std::uint64_t> dims = shape();
  if (dims.empty()) fail("cannot resize a scalar dataset");
  dims[0] = rows;
  if (H5Dset_extent(id(), reinterpret_cast<const hsize_t*>(dims.data())) < 0)
    fail("cannot resize to " + std::to_string(rows) + " rows");
}

// ---- Group --------------------------------------------------------------------------------------

bool Group::has(std::string_view name) const {
  const std::string n(name);
  const htri_t r = H5Lexists(id(), n.c_str(), H5P_DEFAULT);
  if (r < 0) fail("cannot query link " + quoted(name));
  return r > 0;
}

std::vector<std::string> Group::children() const {
  std::vector<std::string> names;
  const herr_t r = H5Literate(
      id(), H5_INDEX_NAME, H5_ITER_INC, nullptr,
      [](hid_t, const char* name, const H5L_info_t*, void* out) -> herr_t {
        static_cast<std::vector<std::string>*>(out)->emplace_back(name);
        return 0;
      },
      &names);
  if (r < 0) fail("cannot list the members");
  return names;
}

Group Group::open_group(std::string_view name) const {
  const std::string n(name);
  Handle g(H5Gopen2(id(), n.c_str(), H5P_DEFAULT));
  if (!g.valid()) fail("missing group " + quoted(name));
  return Group(std::move(g), file_path(), child_path(name));
}

Group Group::create_group(std::string_view name) {
  const std::string n(name);
  Handle g(H5Gcreate2(id(), n.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  if (!g.valid()) fail("cannot create group " + quoted(name));
  return Group(std::move(g), file_path(), child_path(name));
}

Group Group::require_group(std::string_view name) {
  Group g(Handle(H5Iinc_ref(id()) >= 0 ? id() : -1), file_path(), object_path());
  std::size_t start = 0;
  while (start < name.size()) {
    std::size_t end = name.find('/', start);
    if (end == std::string_view::npos) end = name.size();
    const std::string_view part = name.substr(start, end - start);
    if (!part.empty()) g = g.has(part) ? g.open_group(part) : g.create_group(part);
    start = end + 1;
  }
  return g;
}

void Group::remove(std::string_view name) {
  const std::string n(name);
  if (H5Ldelete(id(), n.c_str(), H5P_DEFAULT) < 0) fail("cannot remove " + quoted(name));
}

Dataset Group::open_dataset(std::string_view name) const {
  const std::string n(name);
  if (!has(name)) fail("missing dataset " + quoted(name));
  Handle d(H5Dopen2(id(), n.c_str(), H5P_DEFAULT));
  if (!d.valid()) fail("cannot open dataset " + quoted(name));
  return Dataset(std::move(d), file_path(), child_path(name));
}

Dataset Group::create_dataset(std::string_view name, Scalar type, std::span<const std::uint64_t> shape,
                              const void* data) {
  const std::string n(name);
  Handle space(
      H5Screate_simple(static_cast<int>(shape.size()), reinterpret_cast<const hsize_t*>(shape.data()), nullptr));
  if (!space.valid()) fail("cannot make the dataspace of dataset " + quoted(name));
  Handle d(H5Dcreate2(id(), n.c_str(), file_type(type), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  if (!d.valid()) fail("cannot create dataset " + quoted(name));
  if (element_count(space.get()) > 0 && H5Dwrite(d.get(), memory_type(type), H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
    fail("cannot write dataset " + quoted(name));
  return Dataset(std::move(d), file_path(), child_path(name));
}

Dataset Group::create_extendible(std::string_view name, Scalar type, std::uint64_t width) {
  if (width == 0) fail("dataset " + quoted(name) + ": width must be >= 1");
  const int rank = width == 1 ? 1 : 2;
  const hsize_t dims[2] = {0, width};
  const hsize_t max_dims[2] = {H5S_UNLIMITED, width};
  // About 32 KiB per chunk: small enough that a short series wastes little, large enough that a
  // long one is not mostly chunk index.
  const hsize_t chunk[2] = {std::max<hsize_t>(1, 4096 / width), width};
  Handle space(H5Screate_simple(rank, dims, max_dims));
  Handle props(H5Pcreate(H5P_DATASET_CREATE));
  if (!space.valid() || !props.valid() || H5Pset_chunk(props.get(), rank, chunk) < 0)
    fail("cannot set up extendible dataset " + quoted(name));
  const std::string n(name);
  Handle d(H5Dcreate2(id(), n.c_str(), file_type(type), space.get(), H5P_DEFAULT, props.get(), H5P_DEFAULT));
  if (!d.valid()) fail("cannot create dataset " + quoted(name));
  return Dataset(std::move(d), file_path(), child_path(name));
}

// ---- File ---------------------------------------------------------------------------------------

namespace {
// File access properties shared by create and open:
// - the 1.8 file format at least, so attributes larger than 64 KiB (a long config text) are stored
//   in dense storage instead of being refused;
// - "semi" close degree: H5Fclose fails while objects are open, instead of closing the file
//   behind their back (strong) or silently keeping it open (weak).
// - no HDF5 file locks: a writer's exclusive lock would keep every reader (h5py, h5dump, ParaView)
//   out of a results file for the whole run, and file systems without flock (some NFS and Lustre
//   mounts) fail the open. A reader sees the file as of its last flush. That one process writes a
//   file is the output directory's lock's job (apps/triaxial/lock.hpp), not HDF5's.
Handle access_properties(const std::string& path) {
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS));
  if (!fapl.valid() || H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_LATEST) < 0 ||
      H5Pset_fclose_degree(fapl.get(), H5F_CLOSE_SEMI) < 0)
    throw_error(path, "", "cannot set up file access properties");
#if H5_VERSION_GE(1, 10, 7)
  if (H5Pset_file_locking(fapl.get(), false, true) < 0) throw_error(path, "", "cannot turn off HDF5 file locking");
#endif
  return fapl;
}
}  // namespace

File File::create(const std::filesystem::path& path, std::size_t userblock) {
  silence_hdf5();
  Handle fapl = access_properties(path.string());
  Handle fcpl(H5Pcreate(H5P_FILE_CREATE));
  if (!fcpl.valid() || (userblock > 0 && H5Pset_userblock(fcpl.get(), userblock) < 0))
    throw_error(path.string(), "", "cannot reserve a user block of " + std::to_string(userblock) + " bytes");
  Handle f(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl.get(), fapl.get()));
  if (!f.valid()) throw_error(path.string(), "", "cannot create the file");
  return File(std::move(f), path);
}

File File::create_in_memory(const std::filesystem::path& path) {
  silence_hdf5();
  Handle fapl = access_properties(path.string());
  if (H5Pset_fapl_core(fapl.get(), 64 << 10, 1) < 0) throw_error(path.string(), "", "cannot set up an in-memory file");
  Handle f(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()));
  if (!f.valid()) throw_error(path.string(), "", "cannot create the file in memory");
  return File(std::move(f), path);
}

std::vector<unsigned char> File::image() {
  flush();
  const ssize_t size = H5Fget_file_image(handle_.get(), nullptr, 0);
  if (size < 0) throw_error(path_.string(), "", "cannot get the file image");
  std::vector<unsigned char> bytes(static_cast<std::size_t>(size));
  if (H5Fget_file_image(handle_.get(), bytes.data(), bytes.size()) != size)
    throw_error(path_.string(), "", "cannot get the file image");
  return bytes;
}

File File::open(const std::filesystem::path& path, Mode mode) {
  silence_hdf5();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw_error(path.string(), "", "no such file (or not a regular file)");
  const htri_t is_hdf5 = H5Fis_hdf5(path.c_str());
  if (is_hdf5 <= 0) throw_error(path.string(), "", "not an HDF5 file");
  Handle fapl = access_properties(path.string());
  Handle f(H5Fopen(path.c_str(), mode == Mode::read ? H5F_ACC_RDONLY : H5F_ACC_RDWR, fapl.get()));
  if (!f.valid()) throw_error(path.string(), "", "cannot open the file");
  return File(std::move(f), path);
}

File& File::operator=(File&& other) noexcept {
  if (this != &other) {
    if (handle_.valid()) H5Fclose(handle_.get());
    handle_ = std::move(other.handle_);
    path_ = std::move(other.path_);
  }
  return *this;
}

File::~File() {
  // Errors cannot be thrown from here; close() reports them.
  if (handle_.valid()) {
    H5Fclose(handle_.get());
    H5Eclear2(H5E_DEFAULT);
  }
}

Group File::root() const {
  Handle g(H5Gopen2(handle_.get(), "/", H5P_DEFAULT));
  if (!g.valid()) throw_error(path_.string(), "/", "cannot open the root group");
  return Group(std::move(g), path_.string(), "/");
}

void File::flush() {
  if (H5Fflush(handle_.get(), H5F_SCOPE_GLOBAL) < 0) throw_error(path_.string(), "", "cannot flush");
}

void File::close() {
  if (!handle_.valid()) return;
  if (H5Fclose(handle_.get()) < 0) throw_error(path_.string(), "", "cannot close the file");
  // Closed: the id is gone, so the handle must not release it again.
  handle_.release();
}

}  // namespace sandcell::h5
