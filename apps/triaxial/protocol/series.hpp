#pragma once
// The series of a triaxial results file (/series/<name>, one row per output.series_interval steps;
// docs/physics.md section 8): every column, its units and how it is computed, defined once here.
// The app and the Python module (sandcell.append_row, sandcell.series_columns) write it through
// append_row; a new column is one row of the table in series.cpp.
#include "engine/results.hpp"
#include "engine/state.hpp"
#include "systems/homogenizer.hpp"

#include <cstddef>
#include <span>

namespace sandcell::triaxial {

/// One column of the series: its dataset name, units text, width (values per row) and how a row's
/// values come from the state, the measures and the wall time.
struct SeriesColumn {
  const char* name;
  const char* units;
  std::size_t width;  // 1, 3, 6 or 9
  void (*value)(const State& state, const Measures& m, double wall, double* out);
};

/// Every column, in the order they are written.
std::span<const SeriesColumn> series_columns();

/// Appends one row of every column.
void append_row(ResultsFile& results, const State& state, const Measures& m, double wall);

/// A run that has gone unstable stops here: SimulationError naming the step, the particle id and
/// what is not finite (position, velocity, angular velocity, force), or the cell's stress or lengths.
void check_finite(const State& state, const Measures& m);

}  // namespace sandcell::triaxial
