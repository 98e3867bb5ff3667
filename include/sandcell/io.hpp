#pragma once
// sandcell's public API for files: checkpoints (bitwise restarts), results files (series and
// snapshots) and packings.
#include "engine/checkpoint.hpp"
#include "engine/packing.hpp"
#include "engine/results.hpp"
