#include "protocol/config.hpp"
#include "protocol/config_section.hpp"

#include "protocol/critical.hpp"
#include "protocol/paths.hpp"
#include "protocol/text.hpp"
#include "systems/contact_pass.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <cmath>
#include <map>
#include <numbers>
#include <cstdio>
#include <set>
#include <sstream>

namespace sandcell::triaxial {

const char* path_name(ShearPath path) { return test_path(path).name.data(); }

using namespace config_detail;

namespace {

// The document, or a ConfigError naming the line and column of a syntax error.
toml::table parse_toml(const std::string& text, const std::string& source) {
  try {
    return toml::parse(text, source);
  } catch (const toml::parse_error& e) {
    const auto& where = e.source().begin;
    throw ConfigError(source + ":" + std::to_string(where.line) + ":" + std::to_string(where.column) +
                      ": TOML syntax error: " + std::string(e.description()));
  }
}

// Every top-level key must be one of the known tables.
void check_sections(const toml::table& root, const std::string& source) {
  static const char* const sections[] = {"sample", "material", "contact", "time",  "prepare", "shear",
                                         "tests",  "output",   "watch",   "cyclic", "cell",    "rotation"};
  for (const auto& [key, node] : root) {
    bool known = false;
    for (const char* s : sections) known = known || key.str() == s;
    if (!known || !node.is_table())
      throw ConfigError(source + ": [" + std::string(key.str()) +
                        "]: " + (known ? "must be a table" : "unknown section") +
                        "; allowed sections: [sample] [material] [contact] [time] [prepare] [shear] [tests] [output] "
                        "[watch] [cyclic] [cell] [rotation]");
  }
}


// sample.gradation: rows of [diameter m, percent passing].
void parse_gradation(Section& s, SizeDistribution& sizes) {
  const toml::node* node = s.get("gradation");
  if (!node) return;
  const toml::array* rows = node->as_array();
  if (!rows) s.fail("gradation", Section::describe(*node), "expected an array of [diameter m, percent passing] rows");
  for (std::size_t k = 0; k < rows->size(); ++k) {
    const toml::array* row = rows->get(k)->as_array();
    const auto value = [&](std::size_t q) -> std::optional<double> {
      if (!row || row->size() != 2) return std::nullopt;
      if (auto f = row->get(q)->value_exact<double>()) return *f;
      if (auto i = row->get(q)->value_exact<std::int64_t>()) return static_cast<double>(*i);
      return std::nullopt;
    };
    const auto d = value(0), pct = value(1);
    if (!d || !pct)
      s.fail("gradation[" + std::to_string(k) + "]", Section::describe(*rows->get(k)),
             "expected [diameter m, percent passing], two numbers");
    sizes.table.emplace_back(*d, *pct);
  }
}

// [sample]: a packing file, or the cloud to generate (count, sizes, solid fraction, seed).
void parse_sample(const toml::table& root, const std::string& source, SampleConfig& sample) {
  Section s = section(root, "sample", source);
  GenerationSettings& g = sample.generation;
  g.count = 2000;
  g.sizes.d_min = 5.0e-3;
  g.sizes.d_max = 7.5e-3;
  s.string("file", sample.packing_file);
  s.integer("count", g.count, 2, 10'000'000, "must be an integer in [2, 1e7]");
  s.choice("distribution", g.sizes.kind,
           {{"uniform", SizeDistribution::Kind::uniform}, {"gradation", SizeDistribution::Kind::gradation}});
  s.positive("d_min", g.sizes.d_min, "m");
  s.positive("d_max", g.sizes.d_max, "m");
  parse_gradation(s, g.sizes);
  s.number("solid_fraction", g.solid_fraction, 1e-6, 0.35, "must be in (0, 0.35] (random placement jams near 0.38)");
  s.integer("seed", g.seed, 0, UINT64_MAX, "must be an integer >= 0");
  s.check_unknown();
  if (g.sizes.kind == SizeDistribution::Kind::gradation && g.sizes.table.empty())
    s.fail("gradation", "(missing)", "required when distribution = \"gradation\"");
  if (g.sizes.kind == SizeDistribution::Kind::uniform && !g.sizes.table.empty())
    s.fail(
        "gradation", num(static_cast<double>(g.sizes.table.size()), "(%g rows)"),
        "given with distribution = \"uniform\", which ignores it; allowed: distribution = \"gradation\", or no gradation");
  if (sample.packing_file.empty()) {
    try {
      validate(g);
    } catch (const std::invalid_argument& e) {
      throw ConfigError(source + ": " + e.what());
    }
  }
}

// [material]: the spheres' material (restored for shearing after the preparation's friction).
void parse_material(const toml::table& root, const std::string& source, Material& m) {
  Section s = section(root, "material", source);
  // Solids lie between ~100 kg/m^3 (foams) and 22,600 (osmium); mass scaling of quasi-static DEM
  // multiplies that by up to ~1e6. Far outside, the time step (~ sqrt(density)) vanishes or the
  // inertia swamps the test, and a later check would blame another key (1e-300 blamed material.young).
  s.number("density", m.density, 1.0, 1e10,
           "must be in [1, 1e10] kg/m^3 (solids 100-22,600; mass scaling up to ~1e6 x)");
  s.positive("young", m.young, "Pa");
  s.number("poisson", m.poisson, -0.999, 0.499, "must be in (-1, 0.5)");
  s.number("restitution", m.restitution, 1e-6, 1.0, "must be in (0, 1]");
  s.number("friction", m.friction, 0.0, 10.0, "must be in [0, 10]");
  s.number("rolling_friction", m.rolling_friction, 0.0, 10.0, "must be in [0, 10]");
  s.check_unknown();
}

// [contact]: the contact models and the neighbour list's skin and sorting.
void parse_contact(const toml::table& root, const std::string& source, ContactSettings& k) {
  Section s = section(root, "contact", source);
  k.skin = 0.0;
  k.sort_interval = 1000;
  if (s.string("normal", k.normal)) {
    const std::string names = normal_law_names();  // the registry's (systems/laws/normal_laws.hpp)
    std::string allowed = "allowed:";
    bool known = false;
    for (std::size_t a = 0; a < names.size();) {
      const std::size_t b = std::min(names.find(", ", a), names.size());
      known = known || names.substr(a, b - a) == k.normal;
      allowed += " \"" + names.substr(a, b - a) + "\"";
      a = b + 2;
    }
    if (!known) s.fail("normal", "\"" + k.normal + "\"", allowed);
  }
  // The normal laws' parameters, each a [contact] key, from the registry (systems/laws/law.hpp): the
  // chosen law's are required, another law's refused.
  for (const NormalLawInfo& law : normal_laws())
    for (const LawParameter& q : law.parameters) {
      const std::string key(q.name);
      double value = std::nan("");
      s.number(key, value, q.lo, q.hi,
               "must be in [" + num(q.lo) + ", " + num(q.hi) + "] " + std::string(q.units) + " (" +
                   std::string(q.what) + ")");
      const bool given = !std::isnan(value);
      if (law.name == k.normal && !given)
        s.fail(key, "(none)", "required with normal = \"" + law.name + "\" (" + std::string(q.units) + ", " +
                                  std::string(q.what) + ")");
      if (law.name != k.normal && given) s.fail(key, num(value), "only with normal = \"" + law.name + "\"");
      if (given) k.parameters[key] = value;
    }
  // The laws by their registered names (systems/laws/: TangentialLaws, k_rolling_laws).
  s.registered("tangential", k.tangential, tangential_law_names(), [](const std::string& n) { return tangential_law(n); });
  s.registered("rolling", k.rolling, rolling_law_names(), [](const std::string& n) { return rolling_law(n); });
  s.number("rolling_damping", k.rolling_damping, 0.0, 10.0, "must be in [0, 10]");
  s.number("skin", k.skin, 0.0, 1.0, "must be in [0, 1] m (0: 0.1 x the smallest diameter)");
  s.integer("sort_interval", k.sort_interval, 0, 1'000'000'000, "must be an integer >= 0 steps (0: never)");
  s.boolean("liggghts_compat", k.liggghts_compat);
  s.check_unknown();
}

// [time]: the shearing's time step, a fraction of the Rayleigh time (step = "rayleigh") or from the
// contacts' stiffnesses (step = "stiffness", docs/physics.md section 4.1).
void parse_time(const toml::table& root, const std::string& source, Config& c) {
  Section s = section(root, "time", source);
  s.choice("step", c.dt_rule, {{"rayleigh", TimeStepRule::fixed}, {"stiffness", TimeStepRule::stiffness}});
  const bool stiffness = c.dt_rule == TimeStepRule::stiffness;
  // Each rule's keys would have no effect under the other.
  if (stiffness && s.get("dt_fraction"))
    s.fail("dt_fraction", "given", "acts only with time.step = \"rayleigh\" (the stiffness step's bound: time.max_dt_fraction)");
  for (const char* key : {"safety", "interval", "max_dt_fraction"})
    if (!stiffness && s.get(key)) s.fail(key, "given", "acts only with time.step = \"stiffness\"");
  // Above one Rayleigh time an explicit step through a dense Hertzian packing is unstable
  // (the contact period at overlaps of ~1e-3 R is about 1-3 Rayleigh times).
  s.number("dt_fraction", c.dt_fraction, 1e-6, 1.0,
           "must be in (0, 1] (fraction of the Rayleigh time; stability limit 1)");
  // sqrt 2: the leapfrog's limit on an undamped linear network bounded by the summed stiffnesses.
  s.number("safety", c.dt_safety, 1e-3, std::sqrt(2.0), "must be in [0.001, 1.414] (1.414 = sqrt 2, the stability limit)");
  s.integer("interval", c.dt_interval, 1, 1'000'000, "must be an integer in [1, 1e6] steps");
  s.number("max_dt_fraction", c.max_dt_fraction, 1e-6, 2.0, "must be in (0, 2] (fraction of the Rayleigh time)");
  s.check_unknown();
}

// [prepare]: the isotropic compression to p0 (friction, servo, convergence, chaining).
void parse_prepare(const toml::table& root, const std::string& source, PrepareConfig& p) {
  Section s = section(root, "prepare", source);
  s.number("friction", p.friction, 0.0, 10.0, "must be in [0, 10]");
  s.number("rolling_friction", p.rolling_friction, 0.0, 10.0, "must be in [0, 10]");
  s.number("gain", p.gain, 0.0, 1e9, "must be >= 0 1/s (0: derived)");
  s.positive("max_rate", p.max_rate, "1/s");
  s.number("tolerance", p.tolerance, 1e-9, 0.5, "must be in (0, 0.5]");
  s.number("unbalanced", p.unbalanced, 1e-12, 1.0, "must be in (0, 1]");
  s.integer("check_interval", p.check_interval, 1, 1'000'000'000, "must be an integer >= 1 step");
  s.integer("max_steps", p.max_steps, 1, UINT64_MAX, "must be an integer >= 1 step");
  s.boolean("chain", p.chain);
  s.number("dt_fraction", p.dt_fraction, 1e-6, 1.0,
           "must be in (0, 1] (fraction of the Rayleigh time; default time.dt_fraction)");
  p.target_e0 = s.numbers("target_e0", "a void ratio in (0, 5], or one per tests.p0");
  for (std::size_t k = 0; k < p.target_e0.size(); ++k)
    if (!(p.target_e0[k] > 0.0 && p.target_e0[k] <= 5.0))
      s.fail(p.target_e0.size() == 1 ? "target_e0" : "target_e0[" + std::to_string(k) + "]", num(p.target_e0[k]),
             "must be in (0, 5] (a void ratio)");
  // The search's settings act only with a target: without one each would have no effect.
  const bool target = !p.target_e0.empty();
  for (const char* key : {"target_e0_tolerance", "max_friction", "trial_count"})
    if (!target && s.get(key)) s.fail(key, "given", "acts only with prepare.target_e0; allowed: leave it out");
  s.number("target_e0_tolerance", p.target_tolerance, 1e-4, 0.1, "must be in [1e-4, 0.1] (void ratio)");
  s.number("max_friction", p.max_friction, 0.01, 10.0, "must be in [0.01, 10]");
  s.integer("trial_count", p.trial_count, 100, 10'000'000, "must be an integer in [100, 1e7] spheres");
  s.check_unknown();
}

}  // namespace

double PrepareConfig::target_for(double p0, const std::vector<double>& p0s) const {
  if (target_e0.empty()) return std::nan("");
  if (target_e0.size() == 1) return target_e0.front();
  const auto it = std::find(p0s.begin(), p0s.end(), p0);
  return it == p0s.end() ? std::nan("") : target_e0[static_cast<std::size_t>(it - p0s.begin())];
}

Config load_config(const std::string& path) {
  const bool directory = std::filesystem::is_directory(path);
  std::ifstream in(path);
  if (!in || directory)
    throw ConfigError(path + ": cannot read the configuration file" + (directory ? " (a directory)" : ""));
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return parse_config(buffer.str(), path);
}

Config parse_config(const std::string& text, const std::string& source) {
  Config c;
  c.text = text;
  c.source = source;
  const toml::table root = parse_toml(text, source);
  check_sections(root, source);
  // Table by table, in this order: a config with several faults is refused for the first.
  parse_sample(root, source, c.sample);
  parse_material(root, source, c.material);
  parse_contact(root, source, c.contact);
  parse_time(root, source, c);
  parse_prepare(root, source, c.prepare);
  parse_shear(root, source, c.shear);
  parse_tests(root, source, c);
  parse_output(root, source, c.output);
  parse_watch(root, source, c.watch);
  parse_cyclic(root, source, c.cyclic);
  check_cyclic(c, source);
  parse_cell(root, source, c.cell);
  parse_rotation(root, source, c.rotation);
  check_shearing_cell(c, source);
  check_shear_for_tests(c, source);
  check_prepare_step(c, source);
  check_target_e0(c, source);
  return c;
}

}  // namespace sandcell::triaxial
