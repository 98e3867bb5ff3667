#include "engine/results.hpp"

#include "engine/build_arch.hpp"
#include "engine/field_io.hpp"
#include "engine/hdf5.hpp"
#include "engine/version.hpp"

#include <cerrno>
#include <cstring>
#include <algorithm>
#include <limits>
#include <array>
#include <charconv>
#include <fstream>
#include <stdexcept>
#include <utility>

namespace sandcell {

namespace {

constexpr std::string_view k_format = "sandcell results";

// The particle arrays of a snapshot: what a viewer and the analysis tools need, not the whole
// State (that is what checkpoints are for).
constexpr std::array<std::string_view, 6> k_snapshot_fields = {"id",    "position", "velocity", "angular_velocity",
                                                               "force", "radius"};

std::string snapshot_name(std::uint64_t step) {
  std::string digits = std::to_string(step);
  // Zero-padded so that name order is step order (for h5ls, h5py listings) up to 10^12 steps.
  if (digits.size() < 12) digits.insert(0, 12 - digits.size(), '0');
  return digits;
}

// A snapshot group's step, or false for a name that is not all digits.
bool parse_step(const std::string& name, std::uint64_t& step) {
  const char* end = name.data() + name.size();
  const auto [p, ec] = std::from_chars(name.data(), end, step);
  return !name.empty() && ec == std::errc() && p == end;
}

void check_open(const void* impl) {
  if (impl == nullptr) throw std::logic_error("ResultsFile: the file is closed");
}

void check_format(const h5::Group& root) {
  if (!root.has_attribute("format") || root.get_string("format") != k_format)
    root.fail("not a sandcell results file (no attribute format = \"" + std::string(k_format) + "\")");
  const std::int64_t schema = root.get_value<std::int64_t>("schema_version");
  if (schema != k_results_schema)
    root.fail("results schema version " + std::to_string(schema) + ", this build writes version " +
              std::to_string(k_results_schema));
}

}  // namespace

struct ResultsFile::Impl {
  struct Series {
    h5::Dataset dataset;
    std::size_t width = 0;
    std::string units;
  };

  h5::File file;
  h5::Group series;
  h5::Group snapshots;
  // Open series datasets, so an append does not look the dataset up again.
  std::map<std::string, Series, std::less<>> open_series;

  std::uint64_t pending = 0;  // bytes of series rows appended since the last flush
  // The rows a reopened file kept: a series the resumed run adds that the file lacks (one a newer
  // build writes) starts with this many NaN rows, so that every series stays row-aligned with step.
  std::uint64_t kept_rows = 0;

  explicit Impl(h5::File f) : file(std::move(f)) {}

  // After a failed write every handle is dropped unclosed (h5::File::abandon): the file on disk
  // stays as of its last flush.
  void abandon() noexcept {
    for (auto& [name, s] : open_series) s.dataset.abandon();
    series.abandon();
    snapshots.abandon();
    file.abandon();
  }

  Series& find_series(std::string_view name, std::size_t width, std::string_view units) {
    auto it = open_series.find(name);
    if (it == open_series.end()) {
      if (name.empty() || name.find('/') != std::string_view::npos || name == ".")
        throw std::invalid_argument("ResultsFile: series name '" + std::string(name) + "' (non-empty, no '/')");
      Series s;
      if (series.has(name)) {
        // A series of a resumed run.
        s.dataset = series.open_dataset(name);
        const std::vector<std::uint64_t> shape = s.dataset.shape();
        if (!s.dataset.stores(h5::Scalar::f64) || shape.empty() || shape.size() > 2)
          s.dataset.fail("not a series (float64, shape (rows) or (rows, width))");
        s.width = shape.size() == 2 ? shape[1] : 1;
        s.units = s.dataset.has_attribute("units") ? s.dataset.get_string("units") : "";
      } else {
        s.dataset = series.create_extendible(name, h5::Scalar::f64, width);
        s.dataset.set_string("units", units);
        s.width = width;
        s.units = units;
        const std::vector<double> missing(width, std::numeric_limits<double>::quiet_NaN());
        for (std::uint64_t r = 0; r < kept_rows; ++r) s.dataset.append_row(h5::Scalar::f64, missing.data(), width);
      }
      it = open_series.emplace(std::string(name), std::move(s)).first;
    }
    Series& s = it->second;
    if (s.width != width)
      throw std::invalid_argument("ResultsFile: series '" + std::string(name) + "' has width " +
                                  std::to_string(s.width) + ", got a row of " + std::to_string(width));
    if (s.units != units)
      throw std::invalid_argument("ResultsFile: series '" + std::string(name) + "' is in units '" + s.units +
                                  "', got '" + std::string(units) + "'");
    return s;
  }
};

ResultsFile::ResultsFile(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

template <class Fn>
void ResultsFile::guarded(Fn&& fn) {
  check_open(impl_.get());
  errno = 0;
  try {
    fn();
  } catch (const std::invalid_argument&) {
    throw;  // a caller's mistake, nothing written: the file stays usable
  } catch (const std::exception& e) {
    const int cause = errno;  // of the failed write, when the system said why
    impl_->abandon();
    impl_.reset();
    if (cause == 0 || std::string_view(e.what()).find("disk full") != std::string_view::npos) throw;
    throw std::runtime_error(std::string(e.what()) + " [" + std::strerror(cause) + "]");
  }
}
ResultsFile::ResultsFile(ResultsFile&&) noexcept = default;
ResultsFile& ResultsFile::operator=(ResultsFile&& other) noexcept {
  if (this != &other) {
    try {
      close();
    } catch (...) {
    }
    impl_ = std::move(other.impl_);
  }
  return *this;
}

ResultsFile::~ResultsFile() {
  try {
    close();
  } catch (...) {
    // A destructor cannot report; call close() to see errors.
  }
}

ResultsFile ResultsFile::create(const std::filesystem::path& path, std::string_view config_text,
                                const std::map<std::string, std::string>& attributes) {
  io::require_free_space(path, config_text.size() + (64u << 10));
  auto impl = std::make_unique<Impl>(h5::File::create(path));
  h5::Group root = impl->file.root();
  root.set_string("format", k_format);
  root.set_value<std::int64_t>("schema_version", k_results_schema);
  root.set_string("software_version", version());
  root.set_string("software_arch", build_arch());  // SANDCELL_ARCH: same results for every value
  root.set_string("software_compiler", compiler());
  root.set_string("config", config_text);
  for (const auto& [name, value] : attributes) root.set_string(name, value);
  impl->series = root.create_group("series");
  impl->snapshots = root.create_group("snapshots");
  // On disk from the start: a run killed before its first flush of rows leaves a readable file.
  impl->file.flush();
  return ResultsFile(std::move(impl));
}

ResultsFile ResultsFile::reopen(const std::filesystem::path& path, std::uint64_t last_step) {
  return reopen(path, last_step, last_step);
}

ResultsFile ResultsFile::reopen(const std::filesystem::path& path, std::uint64_t last_row_step,
                                std::uint64_t last_snapshot_step) {
  auto impl = std::make_unique<Impl>(h5::File::open(path, h5::File::Mode::read_write));
  h5::Group root = impl->file.root();
  check_format(root);
  impl->series = root.require_group("series");
  impl->snapshots = root.require_group("snapshots");

  const std::vector<std::string> names = impl->series.children();
  if (!names.empty()) {
    if (!impl->series.has("step")) impl->series.fail("no 'step' series to cut the series back by");
    const std::vector<double> steps = impl->series.open_dataset("step").read<double>();
    // Samples are appended in step order: keep the leading rows up to last_row_step.
    const auto first_after = std::find_if(steps.begin(), steps.end(), [last_row_step](double s) {
      return s > static_cast<double>(last_row_step);
    });
    const std::uint64_t keep = static_cast<std::uint64_t>(first_after - steps.begin());
    for (const std::string& name : names) {
      h5::Dataset d = impl->series.open_dataset(name);
      const std::vector<std::uint64_t> shape = d.shape();
      if (!shape.empty() && shape[0] > keep) d.set_rows(keep);
    }
    impl->kept_rows = keep;
  }
  for (const std::string& name : impl->snapshots.children()) {
    std::uint64_t step = 0;
    if (parse_step(name, step) && step > last_snapshot_step) impl->snapshots.remove(name);
  }
  impl->file.flush();
  return ResultsFile(std::move(impl));
}

void ResultsFile::append(std::string_view name, std::span<const double> values, std::string_view units) {
  check_open(impl_.get());
  if (values.empty()) throw std::invalid_argument("ResultsFile: empty row for series '" + std::string(name) + "'");
  guarded([&] {
    Impl::Series& s = impl_->find_series(name, values.size(), units);
    s.dataset.append_row(h5::Scalar::f64, values.data(), values.size());
    impl_->pending += 8 * values.size();
  });
}

void ResultsFile::append(std::string_view name, double value, std::string_view units) {
  append(name, std::span<const double>(&value, 1), units);
}

void ResultsFile::write_snapshot(const State& state) {
  guarded([&] { write_snapshot_unguarded(state); });
}

void ResultsFile::write_snapshot_unguarded(const State& state) {
  // Every snapshot field is at most 3 doubles a particle: 14 numbers of 8 bytes in all.
  io::require_free_space(impl_->file.path(), 14 * 8 * state.particles.size() + impl_->pending + (64u << 10));
  const std::string name = snapshot_name(state.clock.step);
  if (impl_->snapshots.has(name)) impl_->snapshots.remove(name);
  h5::Group g = impl_->snapshots.create_group(name);
  g.set_value<std::uint64_t>("step", state.clock.step);
  g.set_value<double>("time", state.clock.time);
  g.set_values<double>("cell_length", std::span<const double>(state.cell.length.data(), 3));
  // A cell that shears: its basis's tilts and the flips (H = upper(length, tilt), F = H N H0^-1).
  if (!state.cell.plain()) {
    g.set_values<double>("cell_tilt", std::span<const double>(state.cell.tilt.data(), 3));
    g.set_values<double>("cell_flip", std::span<const double>(state.cell.flip.data(), 3));
  }
  std::size_t written = 0;
  const std::size_t n = state.particles.size();
  for_each_particle_field(state.particles, [&](const FieldInfo& info, const auto& v) {
    if (std::find(k_snapshot_fields.begin(), k_snapshot_fields.end(), info.name) == k_snapshot_fields.end()) return;
    if (v.size() != n)
      throw std::invalid_argument("ResultsFile::write_snapshot: particle field '" + std::string(info.name) + "' has " +
                                  std::to_string(v.size()) + " entries, id has " + std::to_string(n));
    io::write_field(g, info, v);
    ++written;
  });
  // A field renamed in the registry must not silently vanish from snapshots (and the XDMF).
  if (written != k_snapshot_fields.size())
    throw std::logic_error("ResultsFile::write_snapshot: a snapshot field is missing from the registry");
}

void ResultsFile::set_attribute(std::string_view group, std::string_view name, std::string_view value) {
  guarded([&] { impl_->file.root().require_group(group).set_string(name, value); });
}

void ResultsFile::set_attribute(std::string_view group, std::string_view name, double value) {
  guarded([&] { impl_->file.root().require_group(group).set_value<double>(name, value); });
}

void ResultsFile::remove_attribute(std::string_view group, std::string_view name) {
  guarded([&] {
    h5::Group g = impl_->file.root().require_group(group);
    if (g.has_attribute(name)) g.remove_attribute(name);
  });
}

void ResultsFile::flush() {
  guarded([&] {
    // The rows since the last flush and HDF5's metadata (a generous 64 KiB).
    io::require_free_space(impl_->file.path(), impl_->pending + (64u << 10));
    impl_->file.flush();
    impl_->pending = 0;
  });
}

void ResultsFile::close() {
  if (!impl_) return;
  // Every object handle first: the file refuses to close while one is open.
  std::unique_ptr<Impl> impl = std::move(impl_);
  impl->open_series.clear();
  impl->series = h5::Group();
  impl->snapshots = h5::Group();
  const std::filesystem::path path = impl->file.path();
  try {
    io::require_free_space(path, impl->pending + (64u << 10));
    impl->file.close();
  } catch (...) {
    impl->file.abandon();
    throw;
  }
  write_xdmf(path);
}

const std::filesystem::path& ResultsFile::path() const {
  check_open(impl_.get());
  return impl_->file.path();
}

bool ResultsFile::is_open() const { return impl_ != nullptr; }

// ---- XDMF ---------------------------------------------------------------------------------------

std::filesystem::path xdmf_path(const std::filesystem::path& results_path) {
  std::filesystem::path p = results_path;
  p.replace_extension(".xdmf");
  return p;
}

namespace {

std::string xml_escape(std::string_view s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}

// Shortest text that reads back as the same double.
std::string exact(double x) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  return std::string(buf, r.ptr);
}

struct XdmfArray {
  std::string_view name;
  std::string_view attribute_type;  // XDMF AttributeType: "Scalar" or "Vector"
  std::string_view number_type;
  int precision;
  bool vector;
};
constexpr std::array<XdmfArray, 5> k_xdmf_attributes = {{
    {"radius", "Scalar", "Float", 8, false},
    {"id", "Scalar", "UInt", 4, false},
    {"velocity", "Vector", "Float", 8, true},
    {"angular_velocity", "Vector", "Float", 8, true},
    {"force", "Vector", "Float", 8, true},
}};

}  // namespace

std::filesystem::path write_xdmf(const std::filesystem::path& results_path) {
  struct Snapshot {
    std::uint64_t step;
    std::string name;
    double time;
    std::uint64_t n;
  };
  std::vector<Snapshot> snaps;
  {
    const h5::File file = h5::File::open(results_path, h5::File::Mode::read);
    const h5::Group root = file.root();
    if (root.has("snapshots")) {
      const h5::Group g = root.open_group("snapshots");
      for (const std::string& name : g.children()) {
        std::uint64_t step = 0;
        if (!parse_step(name, step)) continue;
        const h5::Group s = g.open_group(name);
        const std::vector<std::uint64_t> shape = s.open_dataset("position").shape();
        if (shape.size() != 2 || shape[1] != 3) s.fail("position is not of shape (n,3)");
        snaps.push_back({step, name, s.get_value<double>("time"), shape[0]});
      }
    }
  }
  std::sort(snaps.begin(), snaps.end(), [](const Snapshot& a, const Snapshot& b) { return a.step < b.step; });

  // References are relative to the sidecar: the HDF5 file by its name, beside it.
  const std::string h5_name = xml_escape(results_path.filename().string());
  std::string xml;
  xml += "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n";
  xml += "<Xdmf Version=\"3.0\">\n";
  xml += "  <Domain>\n";
  xml += "    <Grid Name=\"snapshots\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (const Snapshot& s : snaps) {
    const std::string n = std::to_string(s.n);
    const std::string base = h5_name + ":/snapshots/" + s.name + "/";
    auto data_item = [&](std::string_view field, std::string_view number_type, int precision, bool vector) {
      return "<DataItem Dimensions=\"" + n + (vector ? " 3" : "") + "\" NumberType=\"" + std::string(number_type) +
             "\" Precision=\"" + std::to_string(precision) + "\" Format=\"HDF\">" + base + std::string(field) +
             "</DataItem>";
    };
    xml += "      <Grid Name=\"step " + s.name + "\" GridType=\"Uniform\">\n";
    xml += "        <Time Value=\"" + exact(s.time) + "\"/>\n";
    // One vertex cell per sphere, so that glyph filters and point data both work.
    xml += "        <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" + n + "\" NodesPerElement=\"1\"/>\n";
    xml += "        <Geometry GeometryType=\"XYZ\">\n";
    xml += "          " + data_item("position", "Float", 8, true) + "\n";
    xml += "        </Geometry>\n";
    for (const XdmfArray& a : k_xdmf_attributes) {
      xml += "        <Attribute Name=\"" + std::string(a.name) + "\" AttributeType=\"" +
             std::string(a.attribute_type) + "\" Center=\"Node\">\n";
      xml += "          " + data_item(a.name, a.number_type, a.precision, a.vector) + "\n";
      xml += "        </Attribute>\n";
    }
    xml += "      </Grid>\n";
  }
  xml += "    </Grid>\n";
  xml += "  </Domain>\n";
  xml += "</Xdmf>\n";

  const std::filesystem::path out = xdmf_path(results_path);
  const std::filesystem::path tmp = io::temporary_path(out);
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    f << xml;
    f.close();
    if (!f) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw std::runtime_error("write_xdmf: cannot write " + tmp.string());
    }
  }
  io::commit_file(tmp, out);
  return out;
}

}  // namespace sandcell
