#pragma once
// sandcell's public API for making samples: sphere clouds from a gradation.
#include "engine/generate.hpp"
