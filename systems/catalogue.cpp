#include "systems/catalogue.hpp"

#include "systems/broadphase.hpp"
#include "systems/contact_pass.hpp"
#include "systems/force_gather.hpp"
#include "systems/homogenizer.hpp"
#include "systems/integrate.hpp"
#include "systems/servo.hpp"
#include "systems/spatial_sort.hpp"
#include "systems/wrap.hpp"

namespace sandcell {

std::vector<SystemSpec> systems_for(const Model& model) {
  std::vector<SystemSpec> systems;
  systems.push_back(make_system<IntegrateInitial>());
  if (!model.contact.enabled) systems.push_back(make_system<Wrap>());
  if (model.contact.enabled) {
    if (model.contact.sort_interval > 0) systems.push_back(make_system<SpatialSort>());
    systems.push_back(make_system<Broadphase>());
    systems.push_back(make_system<ContactPass>());
    systems.push_back(make_system<ForceGather>());
  }
  if (model.servo.enabled) {
    systems.push_back(make_system<Homogenizer>());
    systems.push_back(make_system<Servo>());
  }
  systems.push_back(make_system<IntegrateFinal>());
  return systems;
}

}  // namespace sandcell
