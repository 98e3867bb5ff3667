#pragma once
// The registry of normal contact laws: ContactSettings::normal names one of them. A new law is one
// header under systems/laws/ (the interface: systems/laws/law.hpp) and its entry here.
#include "systems/laws/hertz.hpp"
#include "systems/laws/hooke.hpp"

namespace sandcell {

using NormalLaws = LawList<Hertz, Hooke>;

}  // namespace sandcell
