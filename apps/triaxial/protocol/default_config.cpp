// The embedded default test (`triaxial` without a config, `triaxial --print-default`).
#include "protocol/config.hpp"

namespace sandcell::triaxial {

const char* const k_default_config = R"(# sandcell triaxial: the embedded default test.
# ~2000 spheres (d = 5-7.5 mm, uniform by number), prepared isotropically at 0.5 MPa with a
# frictionless preparation, then sheared along constant p = 0.5 MPa with b = 0.5 to 20 % axial
# strain. Every key and its range: apps/triaxial/README.md.
[sample]
count = 2000
distribution = "uniform"
d_min = 5.0e-3
d_max = 7.5e-3
solid_fraction = 0.3
seed = 1

[material]
density = 2650.0
young = 70.0e9
poisson = 0.3
restitution = 0.5
friction = 0.5
rolling_friction = 0.1

[time]
dt_fraction = 0.2

[prepare]
friction = 0.0

[shear]
strain_rate = 1.0
max_axial_strain = 0.2

[tests]
path = "constant_p"
b = 0.5
p0 = 0.5e6

[output]
series_interval = 1000
)";

}  // namespace sandcell::triaxial
