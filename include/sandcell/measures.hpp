#pragma once
// sandcell's public API for the state measures: stress, invariants, strains, void ratio,
// coordination, fabric, energies (measure()), and the contact laws' stored energy.
#include "systems/contact_pass.hpp"
#include "systems/homogenizer.hpp"
#include "systems/stress.hpp"
