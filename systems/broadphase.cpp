#include "systems/broadphase.hpp"

#include "systems/integrate.hpp"  // k_particle_grain
#include "systems/wrap.hpp"

#include "engine/assert.hpp"

#include <algorithm>
#include <type_traits>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <numeric>
#include <string>

namespace sandcell {

namespace {

constexpr const char* k_unstable_advice =
    "the run went unstable (a time step above the stability limit, or loading too fast for the stiffness); "
    "lower dt (time.dt_fraction) or the loading rate";

std::string not_finite_message(ParticleId id, const Vec3& x) {
  return "particle id " + std::to_string(id) + ": position (" + std::to_string(x[0]) + ", " + std::to_string(x[1]) +
         ", " + std::to_string(x[2]) + ") m is not finite: " + k_unstable_advice;
}

bool key_less(ParticleId a_id, const Image& a_img, ParticleId b_id, const Image& b_img) {
  if (a_id != b_id) return a_id < b_id;
  return a_img < b_img;
}

// Bins of the current cell: n_k >= 1 bins per axis in reduced coordinates, each at least `width`
// wide measured perpendicular to the faces (a tilted cell: its widths, Cell::widths). A neighbour
// within the cutoff then differs by at most one bin per axis: |ds_k| = |dual_k . dx| <= cutoff / width_k.
struct Bins {
  std::array<int, 3> n{};
  Vec3 inv_length = Vec3::Zero();
  bool tilted = false;
  Vec3 length = Vec3::Zero(), tilt = Vec3::Zero();  // the basis of a tilted cell
  int index(const std::array<int, 3>& b) const { return (b[2] * n[1] + b[1]) * n[0] + b[0]; }
  std::array<int, 3> of(const Vec3& x) const {
    std::array<int, 3> b{};
    if (tilted) {
      const Vec3 s = reduced(x, length, tilt);
      for (int a = 0; a < 3; ++a) b[a] = std::clamp(static_cast<int>(s[a] * n[a]), 0, n[a] - 1);
      return b;
    }
    for (int a = 0; a < 3; ++a) b[a] = std::clamp(static_cast<int>(x[a] * inv_length[a] * n[a]), 0, n[a] - 1);
    return b;
  }
};

// Calls fn(j, image) for every particle j in the 27 bins around bin `b` with the image shift that
// brings the bin next to b. With 1 or 2 bins on an axis, the three offsets give the same bin with
// different shifts: distinct (j, image) candidates, as a pair may touch through several images.
template <class Fn>
void for_each_neighbor(const Bins& bins, const std::array<int, 3>& b, const std::vector<std::uint32_t>& start,
                       const std::vector<std::uint32_t>& members, Fn&& fn) {
  for (int oz = -1; oz <= 1; ++oz)
    for (int oy = -1; oy <= 1; ++oy)
      for (int ox = -1; ox <= 1; ++ox) {
        const int o[3] = {ox, oy, oz};
        std::array<int, 3> t{};
        Image shift{};
        for (int a = 0; a < 3; ++a) {
          int v = b[a] + o[a];
          std::int8_t s = 0;
          if (v < 0) {
            v += bins.n[a];
            s = -1;
          } else if (v >= bins.n[a]) {
            v -= bins.n[a];
            s = 1;
          }
          t[a] = v;
          shift[a] = s;
        }
        const int bin = bins.index(t);
        for (std::uint32_t q = start[bin]; q < start[bin + 1]; ++q) fn(members[q], shift);
      }
}

// Why a list cannot be built: a non-finite position or cell, or a cell too narrow for the cutoff
// (a sphere would meet its own image); empty when it can.
std::string unbuildable(const std::vector<ParticleId>& id, const std::vector<Vec3>& x, const Cell& cell, double r_max,
                        double skin) {
  const Vec3& length = cell.length;
  // A run gone unstable shows here first as a non-finite position (the rebuild test sends every
  // such step to a build): stop with the particle rather than bin NaNs.
  for (std::size_t k = 0; k < x.size(); ++k)
    if (!x[k].allFinite()) return not_finite_message(id[k], x[k]);
  if (!length.allFinite())
    return "cell lengths (" + std::to_string(length[0]) + ", " + std::to_string(length[1]) + ", " +
           std::to_string(length[2]) +
           ") m are not finite: the servo went unstable (a stress that is not "
           "finite, or a gain too high for the time step)";
  if (!cell.tilt.allFinite())
    return "cell tilts (xy, xz, yz) = (" + std::to_string(cell.tilt[0]) + ", " + std::to_string(cell.tilt[1]) + ", " +
           std::to_string(cell.tilt[2]) + ") m are not finite: the servo went unstable";
  const double cutoff = 2.0 * r_max + skin;
  const Vec3 width = cell.widths();
  if (!(width.minCoeff() > cutoff)) {
    int axis = 0;
    width.minCoeff(&axis);
    return "cell width " + std::string(cell.tilt.isZero(0.0) ? "L" : "(between faces) w") + std::to_string(axis + 1) +
           " = " + std::to_string(width[axis]) + " m is not larger than 2 r_max + skin = " + std::to_string(cutoff) +
           " m (r_max = " + std::to_string(r_max) + " m, skin = " + std::to_string(skin) +
           " m): a sphere would meet its own periodic image";
  }
  return {};
}

// Bins the particles (counting sort, stable in particle index: deterministic): bins of width at
// least `cutoff` in reduced coordinates, their CSR in bp.bin_start / bp.bin_particle.
Bins bin_particles(const std::vector<Vec3>& x, const Cell& cell, double cutoff, BroadphaseScratch& bp) {
  const std::size_t n = x.size();
  const Vec3& length = cell.length;
  const Vec3 width = cell.widths();
  Bins bins;
  int n_bins = 1;
  for (int a = 0; a < 3; ++a) {
    bins.n[a] = std::max(1, static_cast<int>(std::floor(width[a] / cutoff)));
    n_bins *= bins.n[a];
  }
  bins.inv_length = length.cwiseInverse();
  bins.tilted = !cell.tilt.isZero(0.0);
  bins.length = length;
  bins.tilt = cell.tilt;
  bp.bin_start.assign(n_bins + 1, 0);
  bp.particle_bin.resize(n);
  bp.bin_particle.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    bp.particle_bin[k] = bins.index(bins.of(x[k]));
    ++bp.bin_start[bp.particle_bin[k] + 1];
  }
  std::partial_sum(bp.bin_start.begin(), bp.bin_start.end(), bp.bin_start.begin());
  std::vector<std::uint32_t>& fill = bp.count;  // reused as a cursor here
  fill.assign(bp.bin_start.begin(), bp.bin_start.end() - 1);
  for (std::size_t k = 0; k < n; ++k) bp.bin_particle[fill[bp.particle_bin[k]]++] = static_cast<std::uint32_t>(k);
  return bins;
}

// The candidates of particle i: every (j, image) within r_i + r_j + skin, counted once, from the
// particle with the smaller id. Tilted: the image shift H n of a tilted cell (compiled apart, so an
// orthorhombic cell's loop stays as it was).
template <bool Tilted>
struct Candidates {
  const Bins& bins;
  const BroadphaseScratch& bp;
  const std::vector<Vec3>& x;
  const std::vector<double>& radius;
  const std::vector<ParticleId>& id;
  Cell cell;
  double skin;

  template <class Emit>
  void operator()(std::size_t i, Emit&& emit) const {
    const std::array<int, 3> b = bins.of(x[i]);
    const Vec3 xi = x[i];
    const double ri = radius[i] + skin;
    const ParticleId idi = id[i];
    for_each_neighbor(bins, b, bp.bin_start, bp.bin_particle, [&](std::uint32_t j, const Image& img) {
      if (id[j] <= idi) return;
      const Vec3 r = xi - (x[j] + (Tilted ? image_offset(img, cell) : image_offset(img, cell.length)));
      const double cut = ri + radius[j];
      if (r.squaredNorm() < cut * cut) emit(j, img);
    });
  }
};

// Pass 1: candidates per particle into bp.count, their prefix sum into bp.start (each particle's
// slot range). Returns the number of pairs.
template <class Visit>
std::size_t count_pairs(const Visit& visit, std::size_t n, BroadphaseScratch& bp, Executor& exec) {
  bp.count.assign(n, 0);
  exec.parallel_for(n, 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      std::uint32_t c = 0;
      visit(i, [&](std::uint32_t, const Image&) { ++c; });
      bp.count[i] = c;
    }
  });
  bp.start.resize(n + 1);
  bp.start[0] = 0;
  for (std::size_t i = 0; i < n; ++i) bp.start[i + 1] = bp.start[i] + bp.count[i];
  return bp.start[n];
}

// The old list's pairs grouped by particle i into bp.old_start / bp.old_order (a stable counting
// sort: the old list is sorted by i unless the particle arrays were reordered since, which
// remapped its indices).
void group_old_pairs(const ContactPairs& pairs, std::size_t n, BroadphaseScratch& bp) {
  const std::size_t m_old = pairs.size();
  bp.old_start.assign(n + 1, 0);
  for (std::size_t k = 0; k < m_old; ++k) ++bp.old_start[pairs.i[k] + 1];
  std::partial_sum(bp.old_start.begin(), bp.old_start.end(), bp.old_start.begin());
  bp.old_order.resize(m_old);
  bp.count.assign(bp.old_start.begin(), bp.old_start.end() - 1);
  for (std::size_t k = 0; k < m_old; ++k) bp.old_order[bp.count[pairs.i[k]]++] = static_cast<std::uint32_t>(k);
}

// The per-contact histories a scene allocates (components/fields.hpp: for_each_contact_history), by
// element type: 3-vectors (tangential, rolling) and scalars (tangential_radius).
struct Histories {
  std::array<std::vector<Vec3>*, 4> vec{};
  std::size_t n_vec = 0;
  std::array<std::vector<double>*, 4> scalar{};
  std::size_t n_scalar = 0;
};

// A flip of the lattice basis at this build (H' = H E, E unit upper triangular integer): its
// inverse maps an old image to the new basis, n' = E^-1 n (identity when nothing flipped).
struct Flip {
  std::array<int, 3> inverse{};  // (E^-1)_xy, (E^-1)_xz, (E^-1)_yz
  std::array<int, 3> map(const Image& n) const {
    return {n[0] + inverse[0] * n[1] + inverse[1] * n[2], n[1] + inverse[2] * n[2], int(n[2])};
  }
};

// Reduces the tilts of the lattice basis to |yz| <= L2/2, then |xz| <= L1/2, |xy| <= L1/2
// (c <- c - k b, c <- c - k a, b <- b - k a: LAMMPS's box flips, each an exact change of basis of the
// same lattice), counting them in cell.flip (the deformation H N stays continuous: N <- E^-1 N).
Flip reduce_basis(Cell& cell) {
  Flip f;
  if (cell.tilt.isZero(0.0)) return f;
  const auto steps = [](double t, double l) { return std::abs(t) > 0.5 * l ? std::round(t / l) : 0.0; };
  Vec3& t = cell.tilt;
  const Vec3& l = cell.length;
  const double k_yz = steps(t[2], l[1]);
  t[1] -= k_yz * t[0];
  t[2] -= k_yz * l[1];
  const double k_xz = steps(t[1], l[0]);
  t[1] -= k_xz * l[0];
  const double k_xy = steps(t[0], l[0]);
  t[0] -= k_xy * l[0];
  if (k_yz == 0.0 && k_xz == 0.0 && k_xy == 0.0) return f;
  // E = E_yz E_xz E_xy with E_yz = I - k_yz e1 e2^T, E_xz = I - k_xz e0 e2^T, E_xy = I - k_xy e0 e1^T;
  // E^-1 = E_xy^-1 E_xz^-1 E_yz^-1, each E^-1 = I + k e e^T.
  Mat3 inv_yz = Mat3::Identity(), inv_xz = Mat3::Identity(), inv_xy = Mat3::Identity();
  inv_yz(1, 2) = k_yz;
  inv_xz(0, 2) = k_xz;
  inv_xy(0, 1) = k_xy;
  const Mat3 e_inv = inv_xy * inv_xz * inv_yz;
  f.inverse = {int(e_inv(0, 1)), int(e_inv(0, 2)), int(e_inv(1, 2))};
  const Mat3 n = e_inv * cell.flips();  // exact: small integers
  cell.flip = Vec3(n(0, 1), n(0, 2), n(1, 2));
  return f;
}

// Pass 2: fills each particle's slots of the new list (bp.next_pairs, bp.next_history), sorts them
// canonically by (id_j, image) and carries each pair's histories from the old list by key.
template <class Visit>
void fill_pairs(const Visit& visit, std::size_t m, const ContactPairs& pairs, const Histories& hist, const Flip& flip,
                BroadphaseScratch& bp, Executor& exec) {
  const auto& history = hist.vec;
  const std::size_t n_history = hist.n_vec, n_scalar = hist.n_scalar;
  const std::size_t n = visit.x.size();
  const std::vector<ParticleId>& id = visit.id;
  ContactPairs& next = bp.next_pairs;
  next.id_i.resize(m);
  next.id_j.resize(m);
  next.image.resize(m);
  next.i.resize(m);
  next.j.resize(m);
  bp.next_history.resize(n_history);
  for (std::size_t h = 0; h < n_history; ++h) bp.next_history[h].resize(m);
  bp.next_scalar_history.resize(n_scalar);
  for (std::size_t h = 0; h < n_scalar; ++h) bp.next_scalar_history[h].resize(m);
  exec.parallel_for(n, 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      const std::uint32_t s0 = bp.start[i];
      std::uint32_t s = s0;
      visit(i, [&](std::uint32_t j, const Image& img) {
        next.id_j[s] = id[j];
        next.image[s] = img;
        next.j[s] = j;
        ++s;
      });
      // Insertion sort by (id_j, image): a particle has a few tens of candidates at most.
      for (std::uint32_t a = s0 + 1; a < s; ++a)
        for (std::uint32_t c = a; c > s0 && key_less(next.id_j[c], next.image[c], next.id_j[c - 1], next.image[c - 1]);
             --c) {
          std::swap(next.id_j[c], next.id_j[c - 1]);
          std::swap(next.image[c], next.image[c - 1]);
          std::swap(next.j[c], next.j[c - 1]);
        }
      for (std::uint32_t c = s0; c < s; ++c) {
        next.id_i[c] = id[i];
        next.i[c] = static_cast<std::uint32_t>(i);
        // History: the same contact (id_i, id_j, image before the wrap) in the old list of i, if
        // any. With x' = x - s L, r = x_i - x_j - n L = x_i' - x_j' - (n - s_i + s_j) L. After a
        // flip (H' = H E) the old image is first expressed in the new basis: E^-1 n.
        for (std::size_t h = 0; h < n_history; ++h) bp.next_history[h][c].setZero();
        for (std::size_t h = 0; h < n_scalar; ++h) bp.next_scalar_history[h][c] = 0.0;
        const std::array<int, 3>& s_i = bp.shift[i];
        const std::array<int, 3>& s_j = bp.shift[next.j[c]];
        const Image& img = next.image[c];
        const auto same_contact = [&](const Image& old_image) {
          const std::array<int, 3> old = flip.map(old_image);
          return old[0] - s_i[0] + s_j[0] == img[0] && old[1] - s_i[1] + s_j[1] == img[1] &&
                 old[2] - s_i[2] + s_j[2] == img[2];
        };
        for (std::uint32_t q = bp.old_start[i]; q < bp.old_start[i + 1]; ++q)
          if (const std::uint32_t o = bp.old_order[q]; pairs.id_j[o] == next.id_j[c] && same_contact(pairs.image[o])) {
            for (std::size_t h = 0; h < n_history; ++h) bp.next_history[h][c] = (*history[h])[o];
            for (std::size_t h = 0; h < n_scalar; ++h) bp.next_scalar_history[h][c] = (*hist.scalar[h])[o];
            break;
          }
      }
    }
  });
}

}  // namespace

void build_neighbor_list(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  const auto& id = state.read<Component::particle_id>();
  auto& position = state.write<Component::particle_position>();
  const auto& x = position;
  const auto& radius = state.read<Component::particle_radius>();
  Cell& cell = state.write<Component::cell>();
  ContactPairs& pairs = state.write<Component::contact_pairs>();
  // The per-contact histories the scene allocates, from the field registry: carried by key.
  Histories hist;
  for_each_contact_history(state.contacts, [&](const FieldInfo& field, auto& values) {
    check_access(field.component, true);
    if constexpr (std::is_same_v<std::decay_t<decltype(values)>, std::vector<Vec3>>)
      hist.vec[hist.n_vec++] = &values;
    else
      hist.scalar[hist.n_scalar++] = &values;
  });
  auto& reference = state.write<Component::particle_reference>();
  GatherIndex& gather = scratch.write<GatherIndex>();
  BroadphaseScratch& bp = scratch.own<BroadphaseScratch>();

  const std::size_t n = x.size();
  const double skin = model.contact.skin;
  const double r_max = n == 0 ? 0.0 : *std::max_element(radius.begin(), radius.end());
  const Vec3 length = cell.length;
  // A flip first (a tilted cell), then the check of the reduced basis's widths.
  const Flip flip = reduce_basis(cell);
  if (std::string why = unbuildable(id, x, cell, r_max, skin); !why.empty()) {
    scratch.error = std::move(why);
    return;
  }
  const double cutoff = 2.0 * r_max + skin;

  // Positions into the cell: between builds they drift continuously (the images stored with the
  // pairs depend on it); a new list is made from wrapped positions. The shifts are kept: a pair
  // whose sphere was wrapped keeps its contact under another image (old image - s_i + s_j).
  bp.shift.resize(n);
  wrap_positions(position.data(), cell, 0, n, bp.shift.data());

  const Bins bins = bin_particles(x, cell, cutoff, bp);
  const auto list = [&](const auto& visit) {
    const std::size_t m = count_pairs(visit, n, bp, exec);
    group_old_pairs(pairs, n, bp);
    fill_pairs(visit, m, pairs, hist, flip, bp, exec);
  };
  if (bins.tilted)
    list(Candidates<true>{bins, bp, x, radius, id, cell, skin});
  else
    list(Candidates<false>{bins, bp, x, radius, id, cell, skin});

  ContactPairs& next = bp.next_pairs;
  std::swap(pairs.id_i, next.id_i);
  std::swap(pairs.id_j, next.id_j);
  std::swap(pairs.image, next.image);
  std::swap(pairs.i, next.i);
  std::swap(pairs.j, next.j);
  for (std::size_t h = 0; h < hist.n_vec; ++h) std::swap(*hist.vec[h], bp.next_history[h]);
  for (std::size_t h = 0; h < hist.n_scalar; ++h) std::swap(*hist.scalar[h], bp.next_scalar_history[h]);
  pairs.reference_length = length;
  pairs.reference_tilt = cell.tilt;
  reference.assign(x.begin(), x.end());

  rebuild_gather_index(pairs, n, gather);
  rebuild_pair_constants(pairs, radius, state.read<Component::particle_mass>(), scratch.write<PairConstants>());
  bp.cutoff = cutoff;
  bp.r_min = n == 0 ? 0.0 : *std::min_element(radius.begin(), radius.end());
  ++bp.builds;
}

void rebuild_gather_index(const ContactPairs& pairs, std::size_t n, GatherIndex& gather) {
  const std::size_t m = pairs.size();
  // i ranges: the list is sorted by i, so counts and a prefix sum give each particle's run.
  gather.i_start.assign(n + 1, 0);
  for (std::size_t k = 0; k < m; ++k) ++gather.i_start[pairs.i[k] + 1];
  std::partial_sum(gather.i_start.begin(), gather.i_start.end(), gather.i_start.begin());
  // j entries by counting sort, ascending pair index within a particle.
  gather.j_start.assign(n + 1, 0);
  for (std::size_t k = 0; k < m; ++k) ++gather.j_start[pairs.j[k] + 1];
  std::partial_sum(gather.j_start.begin(), gather.j_start.end(), gather.j_start.begin());
  gather.j_entry.resize(m);
  gather.fill.assign(gather.j_start.begin(), gather.j_start.end() - 1);
  for (std::size_t k = 0; k < m; ++k) gather.j_entry[gather.fill[pairs.j[k]]++] = static_cast<std::uint32_t>(k);
  // Visiting order: within each block, by (count as i, count as j, index); a strict total order,
  // so the permutation is unique (std::sort, which allocates nothing).
  gather.visit.resize(n);
  std::iota(gather.visit.begin(), gather.visit.end(), 0u);
  const auto by_counts = [&](std::uint32_t a, std::uint32_t b) {
    const std::uint32_t ia = gather.i_start[a + 1] - gather.i_start[a], ib = gather.i_start[b + 1] - gather.i_start[b];
    if (ia != ib) return ia < ib;
    const std::uint32_t ja = gather.j_start[a + 1] - gather.j_start[a], jb = gather.j_start[b + 1] - gather.j_start[b];
    if (ja != jb) return ja < jb;
    return a < b;
  };
  for (std::size_t b0 = 0; b0 < n; b0 += k_gather_block)
    std::sort(gather.visit.begin() + b0, gather.visit.begin() + std::min(n, b0 + k_gather_block), by_counts);
}

void rebuild_pair_constants(const ContactPairs& pairs, const std::vector<double>& radius,
                            const std::vector<double>& mass, PairConstants& out) {
  const std::size_t m = pairs.size();
  ++out.generation;
  out.r_star.resize(m);
  out.m_star.resize(m);
  out.image_code.resize(m);
  out.r_i.resize(m);
  out.r_j.resize(m);
  for (std::size_t k = 0; k < m; ++k) {
    const std::uint32_t i = pairs.i[k], j = pairs.j[k];
    const Image& img = pairs.image[k];
    // The build gives images of -1, 0 or 1 per axis (the cell is wider than the cutoff); a state
    // handed to World is checked for it (validate in engine/world.cpp).
    SANDCELL_ASSERT(std::abs(img[0]) <= 1 && std::abs(img[1]) <= 1 && std::abs(img[2]) <= 1,
                    "pair image outside -1..1");
    out.image_code[k] = static_cast<std::uint8_t>(9 * (img[2] + 1) + 3 * (img[1] + 1) + (img[0] + 1));
    out.r_i[k] = radius[i];
    out.r_j[k] = radius[j];
    out.r_star[k] = radius[i] * radius[j] / (radius[i] + radius[j]);
    out.m_star[k] = mass[i] * mass[j] / (mass[i] + mass[j]);
  }
}

namespace {

// The rebuild test of Broadphase::run with the non-affine displacement of particle k since the build
// (`displacement`, an orthorhombic or a tilted cell's form: each compiled apart, so the orthorhombic
// loop stays as it was). Returns whether to rebuild; sets Scratch::error on a run gone unstable.
template <class Displacement>
bool rebuild_due(const Model& model, State& state, Scratch& scratch, Executor& exec, const BroadphaseScratch& bp,
                 std::size_t n, double stretch, Displacement&& displacement) {
  // Chunks of the particle passes' size: with 4096, dense-20k's 20,000 particles made 5 chunks,
  // 3 + 2 on 2 threads. A maximum does not depend on how the chunks group it.
  const double d2 = exec.deterministic_reduce(
      n, k_particle_grain, 0.0,
      [&](std::size_t b, std::size_t e) {
        double worst = 0.0;
        for (std::size_t k = b; k < e; ++k) {
          const double d = displacement(k).squaredNorm();
          // A non-finite displacement (a run gone unstable) forces a build, which names it.
          if (!(d <= worst)) worst = d == d ? d : std::numeric_limits<double>::infinity();
        }
        return worst;
      },
      [](double a, double b) { return std::max(a, b); });
  const bool rebuild = !(2.0 * std::sqrt(d2) + stretch * bp.cutoff <= model.contact.skin);
  // The last step passed the test, so every particle had moved at most skin/2 since the build:
  // beyond skin/2 + r_min now, one moved farther than the smallest radius in this one step and
  // may have passed through a contact unseen. That, or a non-finite position, is a run gone
  // unstable: stop with the particle.
  const double limit = 0.5 * model.contact.skin + bp.r_min;
  if (!(d2 <= limit * limit)) {
    const auto& x = state.read<Component::particle_position>();
    std::size_t worst = 0;
    double worst_d = -1.0;
    for (std::size_t k = 0; k < n; ++k) {
      const Vec3 d = displacement(k);
      if (!d.allFinite()) {
        worst = k;
        worst_d = std::numeric_limits<double>::infinity();
        break;
      }
      if (d.norm() > worst_d) worst_d = d.norm(), worst = k;
    }
    const auto& id = state.read<Component::particle_id>();
    if (!std::isfinite(worst_d))
      scratch.error = not_finite_message(id[worst], x[worst]);
    else
      scratch.error = "particle id " + std::to_string(id[worst]) + ": moved " + std::to_string(worst_d) +
                      " m since the neighbour list build, more than skin/2 + r_min = " + std::to_string(limit) +
                      " m: in one step it went farther than the smallest radius (speed " +
                      std::to_string((worst_d - 0.5 * model.contact.skin) / model.dt) +
                      " m/s or more): " + k_unstable_advice;
  }
  return rebuild;
}

}  // namespace

void Broadphase::run(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  const auto& x = state.read<Component::particle_position>();
  const auto& reference = state.read<Component::particle_reference>();
  const Cell& cell = state.read<Component::cell>();
  const ContactPairs& pairs = state.read<Component::contact_pairs>();
  BroadphaseScratch& bp = scratch.own<BroadphaseScratch>();

  bool rebuild = pairs.reference_length.minCoeff() <= 0.0 || reference.size() != x.size();
  if (!rebuild) {
    if (bp.cutoff <= 0.0 || bp.r_min <= 0.0) {  // e.g. after a restart: scratch is not checkpointed
      const auto& radius = state.read<Component::particle_radius>();
      bp.cutoff = 2.0 * *std::max_element(radius.begin(), radius.end()) + model.contact.skin;
      bp.r_min = *std::min_element(radius.begin(), radius.end());
    }
    const Vec3 length = cell.length;
    const Vec3 inv_ref = pairs.reference_length.cwiseInverse();
    // Non-affine displacement since the build: the change of reduced coordinates scaled by the
    // current cell (positions are continuous between builds: no wrap to undo). A tilted cell (now
    // or at the build) takes the reduced coordinates of its upper triangular basis.
    const bool tilted = !cell.tilt.isZero(0.0) || !pairs.reference_tilt.isZero(0.0);
    if (tilted) {
      const Vec3 tilt = cell.tilt, ref_tilt = pairs.reference_tilt, ref_length = pairs.reference_length;
      // The affine change of a branch vector r since the build, |(H H_ref^-1 - I) r|: at most the
      // Frobenius norm times |r|.
      const double stretch = (cell.h() * Cell::upper(ref_length, ref_tilt).inverse() - Mat3::Identity()).norm();
      // H (H^-1 x - s_ref) = x - H s_ref, s_ref = H_ref^-1 x_ref fixed from one build to the next:
      // reduced once per build, not twice per particle per step (six divisions a particle: the
      // rebuild test was 12.8 % of a free-cell triaxial test's time under perf,
      // experiments/2026-11-29-tilted-rebuild); d differs from the reduced form's by round-off only.
      if (bp.reference_reduced.size() != x.size() || bp.reduced_for_build != bp.builds) {
        bp.reference_reduced.resize(x.size());
        Vec3* s = bp.reference_reduced.data();
        exec.parallel_for(x.size(), k_particle_grain, [&](std::size_t b, std::size_t e) {
          for (std::size_t k = b; k < e; ++k) s[k] = reduced(reference[k], ref_length, ref_tilt);
        });
        bp.reduced_for_build = bp.builds;
      }
      const Vec3* s_ref = bp.reference_reduced.data();
      rebuild = rebuild_due(model, state, scratch, exec, bp, x.size(), stretch,
                            [&](std::size_t k) { return Vec3(x[k] - unreduced(s_ref[k], length, tilt)); });
    } else {
      const Vec3 inv_length = length.cwiseInverse();
      // The affine stretch of a branch vector: at most the largest |L/L_ref - 1| times |r|.
      const double stretch = (length.cwiseProduct(inv_ref) - Vec3::Ones()).cwiseAbs().maxCoeff();
      rebuild = rebuild_due(model, state, scratch, exec, bp, x.size(), stretch, [&](std::size_t k) {
        return Vec3((x[k].cwiseProduct(inv_length) - reference[k].cwiseProduct(inv_ref)).cwiseProduct(length));
      });
    }
    if (!scratch.error.empty()) return;
  }
  if (rebuild) build_neighbor_list(model, state, scratch, exec);
}

void Broadphase::setup(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  build_neighbor_list(model, state, scratch, exec);
}

void Broadphase::restore(const Model&, State& state, Scratch& scratch) {
  scratch.own<BroadphaseScratch>().reference_reduced.clear();  // the restored reference's, when next tilted
  rebuild_gather_index(state.contacts.pairs, state.particles.size(), scratch.write<GatherIndex>());
  rebuild_pair_constants(state.contacts.pairs, state.particles.radius, state.particles.mass,
                         scratch.write<PairConstants>());
}

}  // namespace sandcell
