#pragma once
// All of sandcell's public API.
#include "sandcell/generate.hpp"
#include "sandcell/io.hpp"
#include "sandcell/measures.hpp"
#include "sandcell/world.hpp"
#include "engine/version.hpp"
