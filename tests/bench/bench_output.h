// Where the C++ benchmarks write their JSON: `--out DIR` is created if missing, and a file that
// cannot be written ends the benchmark with a message naming it (exit code 2), instead of a
// "wrote …" line over nothing.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

/// Writes `text` to DIR/NAME (DIR created with its parents); returns the path. Exits with code 2
/// and a message on stderr when the folder cannot be created or the file not written.
inline std::string write_bench_file(const std::string& dir, const std::string& name, const std::string& text) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  const std::string path = dir + "/" + name;
  if (ec) {
    std::fprintf(stderr, "error: cannot create the output folder '%s': %s\n", dir.c_str(), ec.message().c_str());
    std::exit(2);
  }
  std::ofstream file(path);
  file << text;
  file.close();
  if (!file) {
    std::fprintf(stderr, "error: cannot write '%s'\n", path.c_str());
    std::exit(2);
  }
  return path;
}
