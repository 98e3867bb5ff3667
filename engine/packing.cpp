#include "engine/packing.hpp"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace sandcell {

Packing read_packing(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open packing file");
  Packing p;
  std::string line;
  std::size_t line_no = 0, expected = 0;
  bool header = false;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    if (!header) {
      double n = 0;
      if (!(fields >> p.box[0] >> p.box[1] >> p.box[2] >> n) || !(p.box.minCoeff() > 0.0) || n < 0 ||
          n != std::floor(n))
        throw std::runtime_error(path + ":" + std::to_string(line_no) +
                                 ": expected header `Lx Ly Lz N` with lengths > 0 m and an integer N >= 0");
      expected = static_cast<std::size_t>(n);
      p.position.reserve(expected);
      p.radius.reserve(expected);
      header = true;
      continue;
    }
    Vec3 x;
    double r = 0;
    if (!(fields >> x[0] >> x[1] >> x[2] >> r) || !(r > 0.0) || !x.allFinite())
      throw std::runtime_error(path + ":" + std::to_string(line_no) +
                               ": expected `x y z r` with finite values, r > 0 m");
    p.position.push_back(x);
    p.radius.push_back(r);
  }
  if (!header) throw std::runtime_error(path + ": no header line `Lx Ly Lz N`");
  if (p.position.size() != expected)
    throw std::runtime_error(path + ": header says N = " + std::to_string(expected) + " spheres, file has " +
                             std::to_string(p.position.size()));
  return p;
}

State make_state(const Model& model, const Packing& packing, std::uint32_t material) {
  State state;
  state.cell.length = state.cell.length0 = packing.box;
  for (std::size_t k = 0; k < packing.position.size(); ++k) {
    Vec3 x = packing.position[k];
    for (int a = 0; a < 3; ++a) x[a] -= packing.box[a] * std::floor(x[a] / packing.box[a]);
    for (int a = 0; a < 3; ++a)
      if (x[a] >= packing.box[a]) x[a] = 0.0;  // round-off of the wrap
    add_sphere(state, model, static_cast<ParticleId>(k), x, packing.radius[k], material);
  }
  return state;
}

Packing tile_packing(const Packing& packing, int k) {
  if (k < 1) throw std::invalid_argument("tile_packing: k = " + std::to_string(k) + ": must be >= 1");
  Packing out;
  out.box = packing.box * static_cast<double>(k);
  const std::size_t n = packing.position.size();
  const std::size_t copies = static_cast<std::size_t>(k) * k * k;
  out.position.reserve(n * copies);
  out.radius.reserve(n * copies);
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j)
      for (int l = 0; l < k; ++l) {
        const Vec3 shift(i * packing.box[0], j * packing.box[1], l * packing.box[2]);
        for (std::size_t a = 0; a < n; ++a) {
          out.position.push_back(packing.position[a] + shift);
          out.radius.push_back(packing.radius[a]);
        }
      }
  return out;
}

}  // namespace sandcell
