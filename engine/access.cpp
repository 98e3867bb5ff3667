#include "engine/access.hpp"

#include "engine/assert.hpp"

#include <string>

namespace sandcell {
namespace {
thread_local const AccessSets* t_current = nullptr;
}

AccessScope::AccessScope(const AccessSets& sets) : previous_(t_current) { t_current = &sets; }
AccessScope::~AccessScope() { t_current = previous_; }

namespace detail {
void check_access_slow(Component c, bool write) {
  const AccessSets* s = t_current;
  if (s == nullptr) return;
  const ComponentMask allowed = write ? s->writes : (s->reads | s->writes);
  if ((allowed & mask_of(c)) != 0) return;
  assert_fail(__FILE__, __LINE__, "declared access",
              "system '" + std::string(s->system) + "' " + (write ? "writes" : "reads") + " component '" +
                  std::string(component_name(c)) + "' outside its declared " + (write ? "write" : "read") + " set");
}
}  // namespace detail

}  // namespace sandcell
