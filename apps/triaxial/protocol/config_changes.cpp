// The configs of a resumed run against the run's own (changed_keys, sample_changes): which keys
// differ, and which of them shape a prepared sample.
#include "protocol/config.hpp"

#include "protocol/text.hpp"

#include "systems/contact_pass.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <map>
#include <set>
#include <sstream>

namespace sandcell::triaxial {

namespace {
std::string repr(const toml::node& n) {
  std::ostringstream v;
  n.visit([&](const auto& el) { v << el; });
  return v.str();
}

// "section.key" -> the value as TOML prints it, for every leaf of the (two-level) config.
std::map<std::string, std::string> flatten(const std::string& text) {
  std::map<std::string, std::string> out;
  const toml::table t = toml::parse(text);
  for (const auto& [section, node] : t) {
    if (const toml::table* inner = node.as_table()) {
      for (const auto& [key, value] : *inner)
        out[std::string(section.str()) + "." + std::string(key.str())] = repr(value);
    } else {
      out[std::string(section.str())] = repr(node);
    }
  }
  return out;
}

bool safe_to_change(const std::string& key) {
  return key.rfind("output.", 0) == 0 || key.rfind("tests.", 0) == 0 || key == "shear.max_axial_strain" ||
         key == "shear.max_deviatoric_strain";
}
}  // namespace

std::vector<std::string> changed_keys(const std::string& before, const std::string& after, bool include_safe) {
  const auto a = flatten(before), b = flatten(after);
  std::vector<std::string> keys;
  for (const auto& [k, v] : a) {
    const auto it = b.find(k);
    if ((it == b.end() || it->second != v) && (include_safe || !safe_to_change(k))) keys.push_back(k);
  }
  for (const auto& [k, v] : b)
    if (!a.count(k) && (include_safe || !safe_to_change(k))) keys.push_back(k);
  std::sort(keys.begin(), keys.end());
  return keys;
}

namespace {

const char* distribution_name(SizeDistribution::Kind k) {
  return k == SizeDistribution::Kind::gradation ? "gradation" : "uniform";
}

// The values of the keys that shape a prepared sample, as text, in the order they are reported.
// material.friction and rolling_friction are left out (the preparation uses prepare.*; the
// material's are restored for shearing), as is prepare.max_steps (it only ends a preparation that
// does not converge). The preparation's step is prepare.dt_fraction, else time.dt_fraction.
std::vector<std::pair<std::string, std::string>> sample_values(const Config& c) {
  const GenerationSettings& g = c.sample.generation;
  const ContactSettings& k = c.contact;
  const PrepareConfig& p = c.prepare;
  std::string gradation;
  for (const auto& [d, pct] : g.sizes.table)
    gradation += (gradation.empty() ? "[" : ", [") + num(d) + ", " + num(pct) + "]";
  std::vector<std::pair<std::string, std::string>> values = {
      {"sample.file", "\"" + c.sample.packing_file + "\""},
      {"sample.count", std::to_string(g.count)},
      {"sample.distribution", distribution_name(g.sizes.kind)},
      {"sample.d_min", num(g.sizes.d_min)},
      {"sample.d_max", num(g.sizes.d_max)},
      {"sample.gradation", "[" + gradation + "]"},
      {"sample.solid_fraction", num(g.solid_fraction)},
      {"sample.seed", std::to_string(g.seed)},
      {"material.density", num(c.material.density)},
      {"material.young", num(c.material.young)},
      {"material.poisson", num(c.material.poisson)},
      {"material.restitution", num(c.material.restitution)},
      {"contact.normal", "\"" + k.normal + "\""},
      {"contact.tangential", tangential_law_name(k.tangential)},
      {"contact.rolling", rolling_law_name(k.rolling)},
      {"contact.rolling_damping", num(k.rolling_damping)},
      {"contact.skin", num(k.skin)},
      {"contact.sort_interval", std::to_string(k.sort_interval)},
      {"contact.liggghts_compat", k.liggghts_compat ? "true" : "false"},
      {"prepare.dt_fraction", num(p.dt_fraction > 0.0 ? p.dt_fraction : c.dt_fraction)},
      {"prepare.friction", num(p.friction)},
      {"prepare.rolling_friction", num(p.rolling_friction)},
      {"prepare.gain", num(p.gain)},
      {"prepare.max_rate", num(p.max_rate)},
      {"prepare.tolerance", num(p.tolerance)},
      {"prepare.unbalanced", num(p.unbalanced)},
      {"prepare.check_interval", std::to_string(p.check_interval)},
      {"prepare.chain", p.chain ? "true" : "false"},
  };
  // The normal laws' parameters ([contact] keys, from the law registry), after contact.normal.
  std::vector<std::pair<std::string, std::string>> parameters;
  for (const NormalLawInfo& law : normal_laws())
    for (const LawParameter& q : law.parameters) {
      const auto it = k.parameters.find(std::string(q.name));
      parameters.emplace_back("contact." + std::string(q.name),
                              it == k.parameters.end() ? "(none)" : num(it->second));
    }
  const auto after_normal =
      std::find_if(values.begin(), values.end(), [](const auto& v) { return v.first == "contact.normal"; });
  values.insert(after_normal + 1, parameters.begin(), parameters.end());
  return values;
}

// Whether a key as written shapes the sample (the fallback of sample_changes).
bool shapes_sample(const std::string& key) {
  static const std::set<std::string> material = {"material.density", "material.young", "material.poisson",
                                                 "material.restitution", "time.dt_fraction"};
  return key.rfind("sample.", 0) == 0 || key.rfind("contact.", 0) == 0 ||
         (key.rfind("prepare.", 0) == 0 && key != "prepare.max_steps") || material.count(key);
}

}  // namespace

std::vector<KeyChange> sample_changes(const std::string& before, const Config& after) {
  std::vector<KeyChange> out;
  Config old;
  try {
    old = parse_config(before, "the sample's config");
  } catch (const ConfigError&) {
    // Written by another version, whose config this one refuses: the keys as written.
    const auto a = flatten(before), b = flatten(after.text);
    std::set<std::string> keys;
    for (const auto* m : {&a, &b})
      for (const auto& [key, value] : *m)
        if (shapes_sample(key)) keys.insert(key);
    for (const std::string& key : keys) {
      const auto x = a.find(key), y = b.find(key);
      const std::string vx = x == a.end() ? "(not given)" : x->second, vy = y == b.end() ? "(not given)" : y->second;
      if (vx != vy) out.push_back({key, vx, vy});
    }
    return out;
  }
  const auto a = sample_values(old), b = sample_values(after);
  for (std::size_t k = 0; k < a.size(); ++k)
    if (a[k].second != b[k].second) out.push_back({a[k].first, a[k].second, b[k].second});
  return out;
}

}  // namespace sandcell::triaxial
