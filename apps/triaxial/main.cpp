// triaxial: true triaxial DEM tests in a stress-controlled periodic cell, from one TOML file.
// Everything happens in triaxial_main (cli.cpp; app.hpp maps the files), a library function, so the
// tests run the app in-process.
#include "run.hpp"

#include <iostream>

int main(int argc, char** argv) { return sandcell::triaxial::triaxial_main(argc, argv, std::cout, std::cerr); }
