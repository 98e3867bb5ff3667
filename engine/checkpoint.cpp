#include "engine/checkpoint.hpp"

#include "engine/field_io.hpp"
#include "engine/fnv1a.hpp"
#include "engine/version.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string_view>
#include <utility>
#include <vector>

namespace sandcell {

namespace {

constexpr std::string_view k_format = "sandcell checkpoint";

std::span<const double> as_span(const Vec3& v) { return {v.data(), 3}; }

Vec3 to_vec3(const h5::Node& node, std::string_view name) {
  const std::vector<double> v = node.get_values<double>(name);
  if (v.size() != 3) node.fail("attribute '" + std::string(name) + "' must hold 3 values");
  return Vec3(v[0], v[1], v[2]);
}

// Refuses a State whose arrays disagree in length: a checkpoint of it could not be read back.
void check_sizes(const State& state) {
  const std::size_t n = state.particles.size();
  for_each_particle_field(state.particles, [n](const FieldInfo& info, const auto& v) {
    if (v.size() != n)
      throw std::invalid_argument("write_checkpoint: particle field '" + std::string(info.name) + "' has " +
                                  std::to_string(v.size()) + " entries, id has " + std::to_string(n));
  });
  const std::size_t m = state.contacts.size();
  for_each_contact_field(state.contacts, [m](const FieldInfo& info, const auto& v) {
    if (v.size() != m)
      throw std::invalid_argument("write_checkpoint: contact field '" + std::string(info.name) + "' has " +
                                  std::to_string(v.size()) + " entries, id_i has " + std::to_string(m));
  });
}

// FNV-1a over the bytes of every registry array, the cell, the clock and the extras, in one fixed
// order: stored with a checkpoint and recomputed from what is read, so a flipped bit anywhere in the
// data is an error naming the file, never a different state.
struct Checksum {
  Fnv1a f;
  void bytes(const void* p, std::size_t n) { f.bytes(p, n); }
  template <class T>
  void values(const std::vector<T>& v) {  // length first: ["a"]["bc"] differs from ["ab"]["c"]
    const std::uint64_t n = v.size();
    f.bytes(&n, sizeof n);
    f.array(v);
  }
  void text(const std::string& s) {
    const std::uint64_t n = s.size();
    f.bytes(&n, sizeof n);
    f.bytes(s.data(), s.size());
  }
};

std::uint64_t checksum(const State& state, const CheckpointExtra& extra) {
  Checksum c;
  for_each_particle_field(state.particles, [&](const FieldInfo&, const auto& v) { c.values(v); });
  for_each_contact_field(state.contacts, [&](const FieldInfo&, const auto& v) { c.values(v); });
  c.bytes(state.contacts.pairs.reference_length.data(), 3 * sizeof(double));
  for (const Vec3* v : {&state.cell.length, &state.cell.length0, &state.cell.rate, &state.cell.servo_integral})
    c.bytes(v->data(), 3 * sizeof(double));
  // A cell that can shear: its tilts, reference, flips, shear rate and shear servo too (an
  // orthorhombic cell's checksum is the one it had before the cell could shear).
  if (!state.cell.plain() || !state.contacts.pairs.reference_tilt.isZero(0.0)) {
    for (const Vec3* v : {&state.cell.tilt, &state.cell.tilt0, &state.cell.flip, &state.cell.shear_rate,
                          &state.cell.shear_integral, &state.contacts.pairs.reference_tilt})
      c.bytes(v->data(), 3 * sizeof(double));
  }
  c.bytes(&state.clock.step, sizeof state.clock.step);
  c.bytes(&state.clock.time, sizeof state.clock.time);
  if (state.clock.dt != 0.0) c.bytes(&state.clock.dt, sizeof state.clock.dt);  // an adaptive step's (older files: none)
  for (const auto& [k, v] : extra.doubles) {
    c.text(k);
    c.values(v);
  }
  for (const auto& [k, v] : extra.integers) {
    c.text(k);
    c.values(v);
  }
  for (const auto& [k, v] : extra.strings) {
    c.text(k);
    c.text(v);
  }
  return c.f.h;
}

// What the engine indexes with must be in range, whatever the file says (a corrupted file whose
// checksum happens to be missing must not crash the engine).
void check_ranges(const std::filesystem::path& path, const State& state) {
  const auto fail = [&](const std::string& what) {
    throw std::runtime_error(path.string() + ": corrupted checkpoint: " + what);
  };
  const std::size_t n = state.particles.size();
  const ContactPairs& c = state.contacts.pairs;
  for (std::size_t k = 0; k < c.size(); ++k) {
    if (c.i[k] >= n || c.j[k] >= n)
      fail("contacts/i or j[" + std::to_string(k) + "] = " + std::to_string(std::max(c.i[k], c.j[k])) + " of " +
           std::to_string(n) + " particles");
    if (state.particles.id[c.i[k]] != c.id_i[k] || state.particles.id[c.j[k]] != c.id_j[k])
      fail("contact " + std::to_string(k) + " does not join the particles its ids name");
  }
  for (std::size_t k = 0; k < n; ++k)
    if (!(state.particles.radius[k] > 0.0) || !(state.particles.mass[k] > 0.0) ||
        !std::isfinite(state.particles.radius[k]))
      fail("particle " + std::to_string(k) + ": radius or mass not > 0");
  if (!(state.cell.length.minCoeff() > 0.0) || !state.cell.length.allFinite()) fail("cell lengths not > 0");
  if (!state.cell.tilt.allFinite() || !state.cell.flip.allFinite() ||
      state.cell.flip != state.cell.flip.array().round().matrix())
    fail("cell tilts not finite or flips not integers");
}

// Keys become HDF5 link names, where '/' separates groups and "." is the group itself.
void check_key(const std::string& key, std::string_view map) {
  if (key.empty() || key == "." || key.find('/') != std::string::npos)
    throw std::invalid_argument("write_checkpoint: extra." + std::string(map) + " key '" + key +
                                "' is not a valid name (non-empty, no '/', not \".\")");
}

void write_contents(h5::File& file, const State& state, const CheckpointExtra& extra) {
  file.root().set_value<std::int64_t>("checksum", static_cast<std::int64_t>(checksum(state, extra)));
  h5::Group root = file.root();
  root.set_string("format", k_format);
  root.set_value<std::int64_t>("schema_version", k_checkpoint_schema);
  root.set_string("software_version", version());

  h5::Group particles = root.create_group("particles");
  particles.set_value<std::uint64_t>("count", state.particles.size());
  for_each_particle_field(state.particles,
                          [&](const FieldInfo& info, const auto& v) { io::write_field(particles, info, v); });

  h5::Group contacts = root.create_group("contacts");
  contacts.set_value<std::uint64_t>("count", state.contacts.size());
  contacts.set_value<std::int64_t>("has_rolling", state.contacts.has_rolling ? 1 : 0);
  contacts.set_value<std::int64_t>("has_tangential_radius", state.contacts.has_tangential_radius ? 1 : 0);
  contacts.set_values<double>("reference_length", as_span(state.contacts.pairs.reference_length));
  contacts.set_values<double>("reference_tilt", as_span(state.contacts.pairs.reference_tilt));
  for_each_contact_field(state.contacts,
                         [&](const FieldInfo& info, const auto& v) { io::write_field(contacts, info, v); });

  h5::Group cell = root.create_group("cell");
  cell.set_values<double>("length", as_span(state.cell.length));
  cell.set_values<double>("length0", as_span(state.cell.length0));
  cell.set_values<double>("rate", as_span(state.cell.rate));
  cell.set_values<double>("servo_integral", as_span(state.cell.servo_integral));
  cell.set_values<double>("tilt", as_span(state.cell.tilt));
  cell.set_values<double>("tilt0", as_span(state.cell.tilt0));
  cell.set_values<double>("flip", as_span(state.cell.flip));
  cell.set_values<double>("shear_rate", as_span(state.cell.shear_rate));
  cell.set_values<double>("shear_integral", as_span(state.cell.shear_integral));

  h5::Group clock = root.create_group("clock");
  clock.set_value<std::uint64_t>("step", state.clock.step);
  clock.set_value<double>("time", state.clock.time);
  if (state.clock.dt != 0.0) clock.set_value<double>("dt", state.clock.dt);

  h5::Group ex = root.create_group("extra");
  h5::Group doubles = ex.create_group("doubles");
  for (const auto& [key, values] : extra.doubles) {
    const std::uint64_t shape[1] = {values.size()};
    doubles.create_dataset<double>(key, values, shape);
  }
  h5::Group integers = ex.create_group("integers");
  for (const auto& [key, values] : extra.integers) {
    const std::uint64_t shape[1] = {values.size()};
    integers.create_dataset<std::int64_t>(key, values, shape);
  }
  h5::Group strings = ex.create_group("strings");
  for (const auto& [key, text] : extra.strings) strings.set_string(key, text);
}

}  // namespace

// An upper bound of a checkpoint's size: every registry array at most 3 doubles an element (24
// bytes) in 11 particle and 10 contact arrays, the extras, and 1 MiB of HDF5 metadata.
namespace {

// A checkpoint's bytes after its first k_userblock are digested (FNV-1a) once it is written, and the
// digest is written into those first bytes, which HDF5 reserves as a user block and never reads.
// read_checkpoint checks the digest before HDF5 parses the file: HDF5 1.10's reader can crash on a
// corrupted file (a double free while releasing a damaged link table in H5G__dense_iterate, found
// by tests/robustness/corrupt_checkpoint.py), and a flipped bit must stop a run with an error naming
// the file, never a signal. A checkpoint written before has no such header and is read as before.
constexpr std::size_t k_userblock = 512;
constexpr std::string_view k_seal = "sandcell checkpoint fnv1a64 ";

// FNV-1a of the file's bytes from k_userblock to its end, and their count.
std::pair<std::uint64_t, std::uint64_t> digest_after_userblock(std::FILE* f, const std::filesystem::path& path) {
  if (std::fseek(f, static_cast<long>(k_userblock), SEEK_SET) != 0)
    throw std::runtime_error(path.string() + ": cannot seek past the checkpoint's header");
  Fnv1a h;
  std::uint64_t count = 0;
  std::vector<unsigned char> buffer(1 << 20);
  for (std::size_t got; (got = std::fread(buffer.data(), 1, buffer.size(), f)) > 0;) {
    h.bytes(buffer.data(), got);
    count += got;
  }
  if (std::ferror(f)) throw std::runtime_error(path.string() + ": cannot read the checkpoint back");
  return {h.h, count};
}

// Writes the digest of a just-closed checkpoint into its user block.
void seal(const std::filesystem::path& path) {
  std::FILE* f = std::fopen(path.c_str(), "r+b");
  if (!f) throw std::runtime_error(path.string() + ": cannot reopen the checkpoint to seal it");
  try {
    const auto [digest, count] = digest_after_userblock(f, path);
    std::string header = std::string(k_seal) + hex_digest(digest) + " " + std::to_string(count) + "\n";
    header.resize(k_userblock, '\0');
    if (std::fseek(f, 0, SEEK_SET) != 0 || std::fwrite(header.data(), 1, header.size(), f) != header.size() ||
        std::fflush(f) != 0)
      throw std::runtime_error(path.string() + ": cannot write the checkpoint's header");
  } catch (...) {
    std::fclose(f);
    throw;
  }
  if (std::fclose(f) != 0) throw std::runtime_error(path.string() + ": cannot close the sealed checkpoint");
}

// Throws, naming the file, when a sealed checkpoint's bytes do not match its digest. An unsealed
// file (no header: written before, or not a checkpoint) is left to HDF5 and the checks after it.
void check_seal(const std::filesystem::path& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return;  // File::open says why
  std::string header(k_userblock, '\0');
  const bool sealed = std::fread(header.data(), 1, header.size(), f) == header.size() &&
                      header.compare(0, k_seal.size(), k_seal) == 0;
  if (!sealed) {
    std::fclose(f);
    return;
  }
  std::pair<std::uint64_t, std::uint64_t> actual;
  try {
    actual = digest_after_userblock(f, path);
  } catch (...) {
    std::fclose(f);
    throw;
  }
  std::fclose(f);
  const std::string recorded = header.substr(k_seal.size(), header.find('\n') - k_seal.size());
  const std::string found = hex_digest(actual.first) + " " + std::to_string(actual.second);
  if (recorded != found)
    throw std::runtime_error(path.string() + ": corrupted checkpoint: its bytes do not match the digest written with "
                             "them (fnv1a64 and size " + recorded.substr(0, 40) + " recorded, " + found + " read)");
}

}  // namespace

static std::uint64_t checkpoint_bytes(const State& state, const CheckpointExtra& extra) {
  std::uint64_t bytes = (1u << 20) + 24u * 11u * state.particles.size() + 24u * 10u * state.contacts.size();
  for (const auto& kv : extra.doubles) bytes += 8 * kv.second.size() + 256;
  for (const auto& kv : extra.integers) bytes += 8 * kv.second.size() + 256;
  for (const auto& kv : extra.strings) bytes += kv.second.size() + 256;
  return bytes;
}

void write_checkpoint(const std::filesystem::path& path, const State& state, const CheckpointExtra& extra) {
  check_sizes(state);
  for (const auto& kv : extra.doubles) check_key(kv.first, "doubles");
  for (const auto& kv : extra.integers) check_key(kv.first, "integers");
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw std::runtime_error("write_checkpoint: " + path.string() + " is a directory");

  const std::filesystem::path tmp = io::temporary_path(path);
  errno = 0;
  try {
    // A full disk is found before HDF5 writes (it may crash closing a file whose write failed);
    // a write that fails anyway leaves the file unclosed and removed.
    io::require_free_space(tmp, checkpoint_bytes(state, extra));
    h5::File file = h5::File::create(tmp, k_userblock);
    try {
      write_contents(file, state, extra);
      file.flush();
      file.close();
    } catch (...) {
      file.abandon();
      throw;
    }
    seal(tmp);
  } catch (const std::exception& e) {
    const int cause = errno;  // of the failed write, when the system said why
    std::filesystem::remove(tmp, ec);
    throw std::runtime_error("write_checkpoint: " + path.string() + " not written: " + e.what() +
                             (cause != 0 ? std::string(" [") + std::strerror(cause) + "]" : std::string()));
  }
  try {
    io::commit_file(tmp, path);
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("write_checkpoint: ") + e.what());
  }
}

State read_checkpoint(const std::filesystem::path& path, CheckpointExtra* extra) {
  check_seal(path);
  const h5::File file = h5::File::open(path, h5::File::Mode::read);
  State state;
  {
    const h5::Group root = file.root();
    if (!root.has_attribute("format") || root.get_string("format") != k_format)
      root.fail("not a sandcell checkpoint (no attribute format = \"" + std::string(k_format) + "\")");
    const std::int64_t schema = root.get_value<std::int64_t>("schema_version");
    if (schema != k_checkpoint_schema)
      root.fail("checkpoint schema version " + std::to_string(schema) + " (written by sandcell " +
                (root.has_attribute("software_version") ? root.get_string("software_version") : "?") +
                "), this build reads version " + std::to_string(k_checkpoint_schema));

    const h5::Group particles = root.open_group("particles");
    const std::uint64_t n = particles.get_value<std::uint64_t>("count");
    for_each_particle_field(state.particles,
                            [&](const FieldInfo& info, auto& v) { io::read_field(particles, info, v, n); });

    const h5::Group contacts = root.open_group("contacts");
    const std::uint64_t m = contacts.get_value<std::uint64_t>("count");
    // Before the walk: the registry lists `rolling` only when it is allocated.
    state.contacts.has_rolling = contacts.get_value<std::int64_t>("has_rolling") != 0;
    // Checkpoints of scenes without mindlin_rescale (and from before it) have none.
    state.contacts.has_tangential_radius = contacts.has_attribute("has_tangential_radius") &&
                                           contacts.get_value<std::int64_t>("has_tangential_radius") != 0;
    state.contacts.pairs.reference_length = to_vec3(contacts, "reference_length");
    // Checkpoints from before the cell could shear hold an orthorhombic cell: zero tilts.
    state.contacts.pairs.reference_tilt =
        contacts.has_attribute("reference_tilt") ? to_vec3(contacts, "reference_tilt") : Vec3::Zero();
    for_each_contact_field(state.contacts,
                           [&](const FieldInfo& info, auto& v) { io::read_field(contacts, info, v, m); });

    const h5::Group cell = root.open_group("cell");
    state.cell.length = to_vec3(cell, "length");
    state.cell.length0 = to_vec3(cell, "length0");
    state.cell.rate = to_vec3(cell, "rate");
    // Checkpoints from before the servo had an integral term carry none: zero, as a stage starts.
    state.cell.servo_integral = cell.has_attribute("servo_integral") ? to_vec3(cell, "servo_integral") : Vec3::Zero();
    const auto optional = [&](const char* key) { return cell.has_attribute(key) ? to_vec3(cell, key) : Vec3::Zero(); };
    state.cell.tilt = optional("tilt");
    state.cell.tilt0 = optional("tilt0");
    state.cell.flip = optional("flip");
    state.cell.shear_rate = optional("shear_rate");
    state.cell.shear_integral = optional("shear_integral");

    const h5::Group clock = root.open_group("clock");
    state.clock.step = clock.get_value<std::uint64_t>("step");
    state.clock.time = clock.get_value<double>("time");
    state.clock.dt = clock.has_attribute("dt") ? clock.get_value<double>("dt") : 0.0;  // an adaptive step's

    if (extra != nullptr) {
      *extra = CheckpointExtra{};
      const h5::Group ex = root.open_group("extra");
      const h5::Group doubles = ex.open_group("doubles");
      for (const std::string& key : doubles.children()) extra->doubles[key] = doubles.open_dataset(key).read<double>();
      const h5::Group integers = ex.open_group("integers");
      for (const std::string& key : integers.children())
        extra->integers[key] = integers.open_dataset(key).read<std::int64_t>();
      const h5::Group strings = ex.open_group("strings");
      for (const std::string& key : strings.attribute_names()) extra->strings[key] = strings.get_string(key);
    }
    // Checkpoints written before the checksum have none; their ranges are still checked.
    if (root.has_attribute("checksum")) {
      CheckpointExtra all;
      const CheckpointExtra& x = extra != nullptr ? *extra : all;
      if (extra == nullptr) {  // the checksum covers the extras too: read them for it
        const h5::Group ex = root.open_group("extra");
        const h5::Group doubles = ex.open_group("doubles");
        for (const std::string& key : doubles.children()) all.doubles[key] = doubles.open_dataset(key).read<double>();
        const h5::Group integers = ex.open_group("integers");
        for (const std::string& key : integers.children())
          all.integers[key] = integers.open_dataset(key).read<std::int64_t>();
        const h5::Group strings = ex.open_group("strings");
        for (const std::string& key : strings.attribute_names()) all.strings[key] = strings.get_string(key);
      }
      if (static_cast<std::uint64_t>(root.get_value<std::int64_t>("checksum")) != checksum(state, x))
        throw std::runtime_error(path.string() +
                                 ": corrupted checkpoint: its data do not match the checksum written with it");
    }
    check_ranges(path, state);
  }
  return state;
}

}  // namespace sandcell
