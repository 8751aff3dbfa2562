// Command line of the C++ benchmarks: [--quick] [--out DIR] SAMPLES_DIR.
#pragma once

#include <string>

struct BenchArguments {
  bool quick = false;     ///< smoke sizes (ctest)
  std::string out = ".";  ///< where the JSON goes
  std::string samples;    ///< the repository's samples/ folder
};

inline BenchArguments bench_arguments(int argc, char** argv) {
  BenchArguments a;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    if (s == "--quick") a.quick = true;
    else if (s == "--out" && i + 1 < argc) a.out = argv[++i];
    else a.samples = s;
  }
  return a;
}
