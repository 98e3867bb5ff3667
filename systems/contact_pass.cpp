#include "systems/contact_pass.hpp"

#include "systems/contact_parts.hpp"

#include "systems/laws/select.hpp"

#include "engine/name_table.hpp"

#include <cmath>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace sandcell {

namespace {

// The kernels of the model's rolling law (contact_parts.hpp).
void run_pass(const Model& model, State& state, Scratch& scratch, Executor& exec, bool update) {
  switch (model.contact.rolling) {
    case RollingModel::none: contact_parts::run_none(model, state, scratch, exec, update); return;
    case RollingModel::epsd2: contact_parts::run_epsd2(model, state, scratch, exec, update); return;
    case RollingModel::epsd: contact_parts::run_epsd(model, state, scratch, exec, update); return;
    case RollingModel::cdt: contact_parts::run_cdt(model, state, scratch, exec, update); return;
  }
}

}  // namespace

void ContactPass::run(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  run_pass(model, state, scratch, exec, true);
}

void ContactPass::setup(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  // The forces of the initial configuration, the histories left as they are (as LAMMPS/LIGGGHTS
  // do in `run 0` setup), so setting up a scene does not advance it.
  run_pass(model, state, scratch, exec, false);
}

void ContactPass::prepare(const Model& model, State& state) {
  with_laws(model.contact, [&](auto normal, auto, auto) {
    using N = typename decltype(normal)::type;
    for (const auto& [key, value] : model.contact.parameters) {
      bool known = false;
      std::string allowed;
      for (const LawParameter& q : N::parameters) {
        known = known || q.name == key;
        allowed += (allowed.empty() ? "" : ", ") + std::string(q.name);
      }
      if (!known)
        throw std::invalid_argument("contact.parameters." + key + ": not a parameter of the " + std::string(N::name) +
                                    " law (" + (allowed.empty() ? "it takes none" : "it takes " + allowed) + ")");
    }
    N::validate(model.contact);
  });
  // Only the tangential laws with a radius history keep one (mindlin_rescale).
  with_laws(model.contact, [&](auto, auto tangential, auto) {
    state.contacts.has_tangential_radius = decltype(tangential)::type::radius_history;
  });
  if (state.contacts.has_tangential_radius)
    state.contacts.tangential_radius.resize(state.contacts.size(), 0.0);
  else
    state.contacts.tangential_radius.clear();
  // Only the laws with a stored moment keep one (cdt has none).
  state.contacts.has_rolling =
      model.contact.rolling == RollingModel::epsd2 || model.contact.rolling == RollingModel::epsd;
  if (!state.contacts.has_rolling) state.contacts.rolling.clear();
}

std::string normal_law_names() { return names_of(NormalLaws{}); }

std::vector<NormalLawInfo> normal_laws() {
  std::vector<NormalLawInfo> out;
  const auto add = [&]<class L>(std::type_identity<L>) {
    out.push_back({std::string(L::name), std::vector<LawParameter>(L::parameters.begin(), L::parameters.end())});
  };
  [&]<class... L>(LawList<L...>) { (add(std::type_identity<L>{}), ...); }(NormalLaws{});
  return out;
}

namespace {
template <class... L>
std::vector<std::pair<std::string, TangentialModel>> tangential_table(LawList<L...>) {
  return {{std::string(L::name), L::id}...};
}
}  // namespace

std::vector<std::string> tangential_law_names() {
  std::vector<std::string> out;
  for (const auto& [name, id] : tangential_table(TangentialLaws{})) out.push_back(name);
  return out;
}
std::optional<TangentialModel> tangential_law(std::string_view name) {
  for (const auto& [n, id] : tangential_table(TangentialLaws{}))
    if (n == name) return id;
  return std::nullopt;
}
std::string tangential_law_name(TangentialModel law) {
  for (const auto& [n, id] : tangential_table(TangentialLaws{}))
    if (id == law) return n;
  return "?";
}
static_assert(in_id_order(k_rolling_laws), "k_rolling_laws: one row per RollingModel, in enum order");

std::vector<std::string> rolling_law_names() {
  std::vector<std::string> out;
  for (const RollingLawInfo& r : k_rolling_laws) out.emplace_back(r.name);
  return out;
}
std::optional<RollingModel> rolling_law(std::string_view name) {
  const RollingLawInfo* r = find_named(std::span<const RollingLawInfo>(k_rolling_laws), name);
  return r ? std::optional<RollingModel>(r->id) : std::nullopt;
}
std::string rolling_law_name(RollingModel law) {
  return std::string(k_rolling_laws[static_cast<std::size_t>(law)].name);
}

double contact_elastic_energy(const Model& model, const State& state) {
  if (model.pairs.empty()) return 0.0;  // a model World has not finalized: no material table
  double elastic = 0.0;
  with_laws(model.contact, [&](auto normal, auto tangential, auto) {
    using N = typename decltype(normal)::type;
    using T = typename decltype(tangential)::type;
    const Particles& p = state.particles;
    const Contacts& c = state.contacts;
    for (std::size_t k = 0; k < c.pairs.size(); ++k) {
      const std::uint32_t i = c.pairs.i[k], j = c.pairs.j[k];
      const Vec3 r = p.position[i] - p.position[j] - image_offset(c.pairs.image[k], state.cell);
      const double reach = p.radius[i] + p.radius[j];
      const double d2 = r.squaredNorm();
      if (!(d2 < reach * reach)) continue;
      const double overlap = reach - std::sqrt(d2);
      const double r_star = p.radius[i] * p.radius[j] / reach;
      const double m_star = p.mass[i] * p.mass[j] / (p.mass[i] + p.mass[j]);
      const PairMaterial& mat = model.pair(p.material[i], p.material[j]);
      const AtRest a = N::at_rest(mat, model.contact, r_star, m_star, overlap);
      elastic += a.energy;
      if (k < c.tangential.size() && a.k_t > 0.0) elastic += T::energy(a.k_t, c.tangential[k].squaredNorm());
      if (c.has_rolling && k < c.rolling.size()) {  // epsd2 or epsd: the laws with a stored moment
        const double k_r = model.contact.rolling == RollingModel::epsd2
                               ? rolling_stiffness<RollingModel::epsd2>(a.k_n, a.k_t, mat.rolling_friction, r_star)
                               : rolling_stiffness<RollingModel::epsd>(a.k_n, a.k_t, mat.rolling_friction, r_star);
        if (k_r > 0.0) elastic += 0.5 * c.rolling[k].squaredNorm() / k_r;
      }
    }
  });
  return elastic;
}

double ContactPass::stable_step(const Model& model, const State& state) {
  return contact_stable_step(model, state).step;
}

StableStepBound contact_stable_step(const Model& model, const State& state) {
  StableStepBound out;
  out.step = std::numeric_limits<double>::infinity();
  if (model.pairs.empty()) return out;  // a model World has not finalized: no material table
  // Through the checked accessors: ContactPass::stable_step_reads, enforced when World calls it.
  const ContactPairs& pairs = state.read<Component::contact_pairs>();
  const auto& id = state.read<Component::particle_id>();
  const auto& position = state.read<Component::particle_position>();
  const auto& radius = state.read<Component::particle_radius>();
  const auto& mass = state.read<Component::particle_mass>();
  const auto& inv_inertia = state.read<Component::particle_inv_inertia>();
  const auto& material = state.read<Component::particle_material>();
  const Cell& cell = state.read<Component::cell>();
  const std::size_t n = position.size();
  std::vector<double> k(6 * n, 0.0);  // per particle: K_x, K_y, K_z, K_rot,x, K_rot,y, K_rot,z
  const bool rolling = model.contact.rolling == RollingModel::epsd2 || model.contact.rolling == RollingModel::epsd;
  with_laws(model.contact, [&](auto normal, auto, auto) {
    using N = typename decltype(normal)::type;
    for (std::size_t q = 0; q < pairs.size(); ++q) {
      const std::uint32_t i = pairs.i[q], j = pairs.j[q];
      const Vec3 r = position[i] - position[j] - image_offset(pairs.image[q], cell);
      const double reach = radius[i] + radius[j];
      const double d2 = r.squaredNorm();
      if (!(d2 < reach * reach)) continue;
      const double d = std::sqrt(d2);
      const Vec3 nrm = r / d;
      const double r_star = radius[i] * radius[j] / reach;
      const double m_star = mass[i] * mass[j] / (mass[i] + mass[j]);
      const PairMaterial& mat = model.pair(material[i], material[j]);
      const AtRest a = N::at_rest(mat, model.contact, r_star, m_star, reach - d);
      const double k_t = mat.friction > 0.0 ? a.k_t : 0.0;
      double k_r = 0.0;
      if (rolling && mat.rolling_friction > 0.0)
        k_r = model.contact.rolling == RollingModel::epsd2
                  ? rolling_stiffness<RollingModel::epsd2>(a.k_n, a.k_t, mat.rolling_friction, r_star)
                  : rolling_stiffness<RollingModel::epsd>(a.k_n, a.k_t, mat.rolling_friction, r_star);
      for (int ax = 0; ax < 3; ++ax) {
        const double n2 = nrm[ax] * nrm[ax];
        const double trans = a.k_tangent * n2 + k_t * (1.0 - n2);
        k[6 * i + ax] += trans;
        k[6 * j + ax] += trans;
        k[6 * i + 3 + ax] += (k_t * radius[i] * radius[i] + k_r) * (1.0 - n2);
        k[6 * j + 3 + ax] += (k_t * radius[j] * radius[j] + k_r) * (1.0 - n2);
      }
    }
  });
  for (std::size_t i = 0; i < n; ++i)
    for (int m = 0; m < 6; ++m) {
      const double stiff = k[6 * i + m];
      if (!(stiff > 0.0)) continue;
      const double inertia = m < 3 ? mass[i] : 1.0 / inv_inertia[i];
      const double step = std::sqrt(inertia / stiff);
      if (step < out.step) out = StableStepBound{step, id[i], m >= 3, stiff};
    }
  return out;
}

}  // namespace sandcell
