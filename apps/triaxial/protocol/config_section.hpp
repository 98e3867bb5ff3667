#pragma once
// The config's table reader and the parsers of its test-side tables, shared by config.cpp (sample,
// material, contact, time, prepare; parse_config) and config_tests.cpp (shear, tests, output, watch,
// cyclic, and the checks across tables). Internal to the protocol library.
#include "protocol/config.hpp"
#include "protocol/text.hpp"

#include <toml++/toml.h>

#include <cmath>
#include <cstdint>
#include <set>
#include <string>
#include <vector>

namespace sandcell::triaxial::config_detail {

// Reads one table, remembering which keys were used so that unknown ones can be reported.
class Section {
 public:
  Section(const toml::table* table, std::string name, const std::string& source)
      : table_(table), name_(std::move(name)), source_(source) {}

  [[noreturn]] void fail(const std::string& key, const std::string& value, const std::string& allowed) const {
    throw ConfigError(source_ + ": " + name_ + "." + key + " = " + value + ": " + allowed);
  }

  const toml::node* get(const std::string& key) {
    used_.insert(key);
    return table_ ? table_->get(key) : nullptr;
  }

  void number(const std::string& key, double& out, double lo, double hi, const std::string& allowed) {
    const toml::node* node = get(key);
    if (!node) return;
    double v = 0.0;
    if (auto f = node->value_exact<double>())
      v = *f;
    else if (auto i = node->value_exact<std::int64_t>())
      v = static_cast<double>(*i);
    else
      fail(key, describe(*node), "expected a number, " + allowed);
    if (!(v >= lo && v <= hi) || !std::isfinite(v)) fail(key, num(v), allowed);
    out = v;
  }
  void positive(const std::string& key, double& out, const std::string& units) {
    number(key, out, std::nextafter(0.0, 1.0), HUGE_VAL, "must be > 0 " + units);
  }
  void integer(const std::string& key, std::uint64_t& out, std::uint64_t lo, std::uint64_t hi,
               const std::string& allowed) {
    const toml::node* node = get(key);
    if (!node) return;
    auto i = node->value_exact<std::int64_t>();
    if (!i) fail(key, describe(*node), "expected an integer, " + allowed);
    if (*i < 0 || static_cast<std::uint64_t>(*i) < lo || static_cast<std::uint64_t>(*i) > hi)
      fail(key, std::to_string(*i), allowed);
    out = static_cast<std::uint64_t>(*i);
  }
  void integer(const std::string& key, int& out, int lo, int hi, const std::string& allowed) {
    std::uint64_t v = static_cast<std::uint64_t>(std::max(out, 0));
    const toml::node* node = get(key);
    if (!node) return;
    auto i = node->value_exact<std::int64_t>();
    if (!i) fail(key, describe(*node), "expected an integer, " + allowed);
    if (*i < lo || *i > hi) fail(key, std::to_string(*i), allowed);
    v = static_cast<std::uint64_t>(*i);
    out = static_cast<int>(v);
  }
  void boolean(const std::string& key, bool& out) {
    const toml::node* node = get(key);
    if (!node) return;
    auto b = node->value_exact<bool>();
    if (!b) fail(key, describe(*node), "expected true or false");
    out = *b;
  }
  bool string(const std::string& key, std::string& out) {
    const toml::node* node = get(key);
    if (!node) return false;
    auto s = node->value_exact<std::string>();
    if (!s) fail(key, describe(*node), "expected a string");
    out = *s;
    return true;
  }
  template <class E>
  void choice(const std::string& key, E& out, std::initializer_list<std::pair<const char*, E>> options) {
    std::string s;
    if (!string(key, s)) return;
    std::string allowed = "allowed:";
    for (const auto& [text, value] : options) {
      if (s == text) {
        out = value;
        return;
      }
      allowed += std::string(" \"") + text + "\"";
    }
    fail(key, "\"" + s + "\"", allowed);
  }
  /// One of `names` (a law registry's), parsed by `parse` into `out`.
  template <class E, class Parse>
  void registered(const std::string& key, E& out, const std::vector<std::string>& names, Parse parse) {
    std::string s;
    if (!string(key, s)) return;
    if (const auto v = parse(s)) {
      out = *v;
      return;
    }
    std::string allowed = "allowed:";
    for (const std::string& n : names) allowed += " \"" + n + "\"";
    fail(key, "\"" + s + "\"", allowed);
  }
  /// A number or an array of numbers.
  std::vector<double> numbers(const std::string& key, const std::string& allowed) {
    const toml::node* node = get(key);
    std::vector<double> out;
    if (!node) return out;
    const auto one = [&](const toml::node& n, const std::string& where) {
      if (auto f = n.value_exact<double>()) return *f;
      if (auto i = n.value_exact<std::int64_t>()) return static_cast<double>(*i);
      fail(where, describe(n), "expected a number, " + allowed);
    };
    if (const toml::array* a = node->as_array()) {
      for (std::size_t k = 0; k < a->size(); ++k) out.push_back(one(*a->get(k), key + "[" + std::to_string(k) + "]"));
      if (out.empty()) fail(key, "[]", "expected at least one value, " + allowed);
    } else {
      out.push_back(one(*node, key));
    }
    return out;
  }
  std::vector<std::string> strings(const std::string& key) {
    const toml::node* node = get(key);
    std::vector<std::string> out;
    if (!node) return out;
    const auto one = [&](const toml::node& n, const std::string& where) {
      if (auto s = n.value_exact<std::string>()) return *s;
      fail(where, describe(n), "expected a string");
    };
    if (const toml::array* a = node->as_array()) {
      for (std::size_t k = 0; k < a->size(); ++k) out.push_back(one(*a->get(k), key + "[" + std::to_string(k) + "]"));
      if (out.empty()) fail(key, "[]", "expected at least one value");
    } else {
      out.push_back(one(*node, key));
    }
    return out;
  }
  void check_unknown() const {
    if (!table_) return;
    for (const auto& [key, node] : *table_)
      if (!used_.count(std::string(key.str()))) {
        std::string allowed = "unknown key; allowed keys in [" + name_ + "]:";
        for (const std::string& k : used_) allowed += " " + k;
        fail(std::string(key.str()), describe(node), allowed);
      }
  }
  static std::string describe(const toml::node& node) {
    std::ostringstream out;
    if (node.is_string())
      out << '"' << *node.value<std::string>() << '"';
    else if (node.is_table())
      out << "(a table)";
    else if (node.is_array())
      out << "(an array)";
    else
      node.visit([&](const auto& v) { out << v; });
    // A value is echoed in one-line messages: a long one is cut.
    std::string text = out.str();
    if (text.size() > 60) text = text.substr(0, 57) + "...";
    return text;
  }

 private:
  const toml::table* table_;
  std::string name_;
  const std::string& source_;
  std::set<std::string> used_;
};

// The reader of table `name` (absent: every key keeps its default).
inline Section section(const toml::table& root, const char* name, const std::string& source) {
  return Section(root.get_as<toml::table>(name), name, source);
}

void parse_shear(const toml::table& root, const std::string& source, ShearConfig& h);
void parse_tests(const toml::table& root, const std::string& source, Config& c);
void parse_output(const toml::table& root, const std::string& source, OutputConfig& o);
void parse_watch(const toml::table& root, const std::string& source, WatchConfig& w);
void parse_cyclic(const toml::table& root, const std::string& source, CyclicConfig& c);
void check_cyclic(const Config& c, const std::string& source);
void parse_cell(const toml::table& root, const std::string& source, CellConfig& c);
void parse_rotation(const toml::table& root, const std::string& source, RotationConfig& r);
void check_shearing_cell(const Config& c, const std::string& source);
void check_shear_for_tests(const Config& c, const std::string& source);
void check_prepare_step(const Config& c, const std::string& source);
void check_target_e0(const Config& c, const std::string& source);

}  // namespace sandcell::triaxial::config_detail
