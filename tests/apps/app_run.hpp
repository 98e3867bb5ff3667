#pragma once
// Helpers of the triaxial app's tests (test_triaxial.cpp, test_triaxial_path.cpp): the app run
// in-process, fresh directories, files, and HDF5 datasets and attributes read with the C API
// (independent of the engine's writer).
#include "run.hpp"

#include <unistd.h>

#include <doctest/doctest.h>
#include <hdf5.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace app_test {

namespace fs = std::filesystem;

// A small, soft sample that prepares in seconds: 300 spheres, E = 1 GPa (dt 8x the default's),
// p0 = 0.1 MPa.
inline const std::string k_small = R"([sample]
count = 300
d_min = 5.0e-3
d_max = 7.5e-3
seed = 3
[material]
young = 1.0e9
[prepare]
max_rate = 20.0
check_interval = 500
[shear]
strain_rate = 2.0
max_axial_strain = 0.03
[tests]
path = "constant_p"
b = 0.5
p0 = 0.1e6
[output]
series_interval = 100
plot = false
)";

struct Result {
  int code = 0;
  std::string out, err;
};

inline Result run(std::vector<std::string> args) {
  args.insert(args.begin(), "triaxial");
  std::vector<const char*> argv;
  for (const std::string& a : args) argv.push_back(a.c_str());
  std::ostringstream out, err;
  Result r;
  r.code = sandcell::triaxial::triaxial_main(static_cast<int>(argv.size()), argv.data(), out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}

// An empty directory of this process's (the pid in its name: two test runs at once, e.g. from two
// checkouts, never share one).
inline fs::path fresh_dir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("sandcell_test_triaxial_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

inline void write(const fs::path& path, const std::string& text) { std::ofstream(path) << text; }

inline std::string read(const fs::path& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// A whole dataset of doubles.
inline std::vector<double> dataset(const fs::path& file, const std::string& name) {
  std::vector<double> v;
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(f >= 0);
  const hid_t d = H5Dopen2(f, name.c_str(), H5P_DEFAULT);
  REQUIRE(d >= 0);
  const hid_t space = H5Dget_space(d);
  const hssize_t n = H5Sget_simple_extent_npoints(space);
  v.resize(static_cast<std::size_t>(n));
  if (n > 0) REQUIRE(H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) >= 0);
  H5Sclose(space);
  H5Dclose(d);
  H5Fclose(f);
  return v;
}

inline bool has_link(const fs::path& file, const std::string& name) {
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return false;
  const bool yes = H5Lexists(f, name.c_str(), H5P_DEFAULT) > 0;
  H5Fclose(f);
  return yes;
}

// A string attribute of the root group ("" when absent).
inline std::string string_attribute(const fs::path& file, const char* name) {
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(f >= 0);
  std::string value;
  if (H5Aexists(f, name) > 0) {
    const hid_t a = H5Aopen(f, name, H5P_DEFAULT);
    const hid_t type = H5Aget_type(a);
    if (H5Tis_variable_str(type) > 0) {
      char* text = nullptr;
      H5Aread(a, type, &text);
      value = text ? text : "";
      H5free_memory(text);
    } else {
      value.resize(H5Tget_size(type));
      H5Aread(a, type, value.data());
      value = value.c_str();
    }
    H5Tclose(type);
    H5Aclose(a);
  }
  H5Fclose(f);
  return value;
}

}  // namespace app_test
