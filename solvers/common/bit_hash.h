// Two independent 64-bit hashes of a stream of values, bit for bit (doubles by their bits): the
// identity of an input that is reused when it recurs exactly (element systems kept between
// solves, in/out verdicts of result points kept between runs). Equal inputs give equal hashes;
// two different inputs collide in both with probability ~2^-128.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <cstring>

namespace parafab {

inline uint64_t splitmix64(uint64_t x) {  // splitmix64 finalizer
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

struct BitHash {
  uint64_t h1 = 0x243f6a8885a308d3ULL, h2 = 0x13198a2e03707344ULL;
  void add(uint64_t v) {
    h1 = splitmix64(h1 ^ v);
    h2 = splitmix64(h2 + 0x632be59bd9b4e019ULL * (v + 1));
  }
  void add(double d) {
    uint64_t v;
    std::memcpy(&v, &d, sizeof v);
    add(v);
  }
  void add(const Eigen::Vector3d& v) { add(v.x()), add(v.y()), add(v.z()); }
};

}  // namespace parafab
