// A seeded random-mutation fuzzer over the entry points' JSON readers and the STEP reader
// (issue 53, "Inputs and faults"). Seeds are the samples; each case mutates one (JSON: keys
// deleted, renamed or added, values replaced by other types, extreme or non-integral numbers,
// arrays emptied or grown; STEP: truncated, lines dropped or repeated, numbers and bytes
// changed) and runs the entry on it in a forked child with a time limit. A case passes when the
// entry returns or throws parafab::Error (an input error naming the problem); it fails when it
// throws anything else (the CLI's "internal error") or the child dies (a crash). Slow cases are
// counted, not failed. Failing inputs are saved for replay:
//   fuzz_inputs SAMPLES_DIR OUT_DIR [--seconds S] [--seed N] [--case-seconds T] [--max-cases C]
// The cases of a seed come in a fixed order, so a run of C cases is the same on every machine
// (CI uses a fixed count within a time budget; new seeds are for longer runs by hand).
//   fuzz_inputs --replay FORMAT FILE [PART]
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "common/error.h"
#include "optimize_json.h"
#include "part_json.h"
#include "part_preflight.h"
#include "revolution_json.h"
#include "rod_json.h"
#include "sections_json.h"
#include "simulate_json.h"
#include "stability_json.h"
#include "strip_improve_json.h"
#include "strip_json.h"
#include "strip_stabilize_json.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct Seed {
  std::string format;  // strip, strip-stability, strip-improve, strip-stabilize, rod, revolution, simulate, optimize, sections, step
  std::string text;    // the JSON request, or the STEP file's text
  std::string part;    // the part a job runs on ("" for requests)
};

std::string read_text(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::vector<Seed> seeds(const fs::path& samples) {
  std::vector<Seed> out;
  auto each = [&](const char* folder, auto fn) {
    for (const auto& e : fs::directory_iterator(samples / folder))
      if (e.path().extension() == ".json") fn(e.path());
  };
  each("strips", [&](const fs::path& p) {
    const std::string t = read_text(p);
    for (const char* f : {"strip", "strip-stability", "strip-improve", "strip-stabilize"}) out.push_back({f, t, ""});
  });
  each("rods", [&](const fs::path& p) { out.push_back({"rod", read_text(p), ""}); });
  each("revolution", [&](const fs::path& p) { out.push_back({"revolution", read_text(p), ""}); });
  each("simulations", [&](const fs::path& p) {
    out.push_back({"simulate", read_text(p), (samples / "parts" / (p.stem().string() + ".step")).string()});
  });
  each("optimizations", [&](const fs::path& p) {
    out.push_back({"optimize", read_text(p), (samples / "parts" / (p.stem().string() + ".step")).string()});
  });
  // A cheap optimization: the wheel's volume on its own parameters.
  out.push_back({"optimize", R"({"objective": {"type": "volume"}, "parameters": "auto",
                 "constraints": [{"type": "volume", "min_ratio": 0.9}], "fixed_faces": [0]})",
                 (samples / "parts" / "wheel.step").string()});
  each("sections", [&](const fs::path& p) {
    const json j = json::parse(read_text(p));
    const fs::path part = j.contains("part") ? samples / "parts" / j["part"].get<std::string>()
                                             : samples / "surfaces" / (p.stem().string() + ".step");
    out.push_back({"sections", j.dump(), fs::exists(part) ? part.string() : (samples / "surfaces" / (p.stem().string() + ".step")).string()});
  });
  for (const char* part : {"box.step", "cylinder.step", "l_bracket.step"})
    out.push_back({"step", read_text(samples / "parts" / part), ""});
  return out;
}

// ---- JSON mutations
json random_value(std::mt19937_64& rng) {
  static const json values[] = {nullptr, true, false, 0, -1, 1, 2.5, -2.5, 1e308, -1e308, 1e20, 4294967296.0,
                                9223372036854775807LL, "x", "", json::array(), json::object(),
                                json::array({1, 2, 3}), json::array({json::array({0, 0}), json::array({1, 1})}),
                                json::array({json::array({0, 0, 0})}), json::object({{"face", 0}}),
                                json::object({{"point", json::array({0, 0, 0})}}), "auto", 1e-300, -0.0};
  return values[rng() % (sizeof(values) / sizeof(values[0]))];
}

// Every node of `j` (pointer paths), so one can be picked uniformly.
void nodes(const json& j, const json::json_pointer& at, std::vector<json::json_pointer>& out) {
  out.push_back(at);
  if (j.is_object())
    for (auto it = j.begin(); it != j.end(); ++it) nodes(*it, at / it.key(), out);
  else if (j.is_array())
    for (size_t i = 0; i < j.size(); ++i) nodes(j[i], at / std::to_string(i), out);
}

void mutate(json& root, std::mt19937_64& rng) {
  std::vector<json::json_pointer> all;
  nodes(root, json::json_pointer(), all);
  const json::json_pointer at = all[rng() % all.size()];
  json& node = root[at];
  const bool top = at.empty();
  switch (rng() % 9) {
    case 0:  // delete this key / element
      if (!top) {
        json& parent = root[at.parent_pointer()];
        if (parent.is_object()) parent.erase(at.back());
        else if (parent.is_array() && !parent.empty()) parent.erase(parent.begin() + std::stoul(at.back()));
      }
      break;
    case 1:
    case 2:  // another value (other types, extremes)
      if (!top) node = random_value(rng);
      break;
    case 3:  // a number scaled or made non-integral
      if (node.is_number()) {
        static const double f[] = {-1, 0, 1e6, 1e-6, 1.5, 1e30};
        node = node.get<double>() * f[rng() % 6] + (rng() % 2 ? 0.5 : 0.0);
      }
      break;
    case 4:  // a key renamed (a typo)
      if (node.is_object() && !node.empty()) {
        auto it = node.begin();
        std::advance(it, rng() % node.size());
        std::string k = it.key();
        json v = *it;
        node.erase(k);
        node[k + "x"] = v;
      }
      break;
    case 5:  // an array emptied
      if (node.is_array()) node = json::array();
      break;
    case 6:  // an array grown (its first item repeated)
      if (node.is_array() && !node.empty())
        for (int k = 0; k < 3; ++k) node.push_back(node[0]);
      break;
    case 7:  // a key added to an object
      if (node.is_object()) node["fuzz"] = random_value(rng);
      break;
    case 8:  // an array shortened to one item
      if (node.is_array() && node.size() > 1) node.erase(node.begin() + 1, node.end());
      break;
  }
}

// ---- STEP mutations
std::string mutate_step(std::string s, std::mt19937_64& rng) {
  if (s.empty()) return s;
  switch (rng() % 5) {
    case 0:  // truncated
      s.resize(rng() % s.size());
      break;
    case 1: {  // a line dropped
      size_t a = rng() % s.size();
      a = s.rfind('\n', a);
      const size_t b = s.find('\n', a == std::string::npos ? 0 : a + 1);
      if (a != std::string::npos && b != std::string::npos) s.erase(a, b - a);
      break;
    }
    case 2: {  // a line repeated
      size_t a = s.rfind('\n', rng() % s.size());
      const size_t b = s.find('\n', a == std::string::npos ? 0 : a + 1);
      if (a != std::string::npos && b != std::string::npos) s.insert(b, s.substr(a, b - a));
      break;
    }
    case 3: {  // a number changed
      for (int tries = 0; tries < 50; ++tries) {
        const size_t i = rng() % s.size();
        if (std::isdigit(static_cast<unsigned char>(s[i]))) {
          s[i] = "0123456789"[rng() % 10];
          if (rng() % 4 == 0) s.insert(i, "1E30");
          break;
        }
      }
      break;
    }
    case 4:  // bytes changed
      for (int k = 0; k < 8; ++k) s[rng() % s.size()] = static_cast<char>(rng() % 256);
      break;
  }
  return s;
}

// Runs one case in this process: 0 handled (result or parafab::Error), 1 another exception.
int run_case(const std::string& format, const std::string& text, const std::string& part, const std::string& tmp) {
  using namespace parafab::entry;
  try {
    if (format == "step") {
      const std::string path = tmp + "/part.step";
      std::ofstream(path) << text;
      preflight_part_read(path);  // as the CLI reads a part: a crashing OCCT is an input error
      inspect_part_json(path);
      return 0;
    }
    const json j = json::parse(text);
    if (format == "strip") design_strip_json(j);
    else if (format == "strip-stability") strip_stability_json(j);
    else if (format == "strip-improve") improve_strip_json(j, 0);
    else if (format == "strip-stabilize") stabilize_strip_json(j, 0);
    else if (format == "rod") design_rod_json(j);
    else if (format == "revolution") revolution_strips_json(j);
    else if (format == "simulate") SimulationSession(part, j).estimate();  // the reading, not the solve
    else if (format == "optimize") optimize_part_json(part, j, tmp + "/out");
    else if (format == "sections") strip_sections_json(part, j);
    return 0;
  } catch (const parafab::Error&) {
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "not an input error: " << e.what() << "\n";
    return 1;
  } catch (...) {
    std::cerr << "not an input error: an exception of another type\n";
    return 1;
  }
}

// The case's JSON made quick where it would only be slow: an optimization applies its start
// (max_iterations 0), a simulation only reads and estimates.
std::string quick(const std::string& format, json j) {
  if (format == "optimize" && j.is_object()) j["max_iterations"] = 0, j["chart"] = false;
  return j.dump();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 4 && std::string(argv[1]) == "--replay") {
    const std::string tmp = fs::temp_directory_path() / ("parafab-fuzz-replay-" + std::to_string(::getpid()));
    fs::create_directories(tmp);
    const int code = run_case(argv[2], read_text(argv[3]), argc > 4 ? argv[4] : "", tmp);
    fs::remove_all(tmp);
    std::cout << (code == 0 ? "handled" : "NOT an input error") << "\n";
    return code;
  }
  if (argc < 3) {
    std::cerr << "usage: fuzz_inputs SAMPLES_DIR OUT_DIR [--seconds S] [--seed N] [--case-seconds T]\n";
    return 2;
  }
  const fs::path samples = argv[1], out = argv[2];
  double budget = 60, case_seconds = 10;
  uint64_t seed = 1;
  long max_cases = -1;
  for (int i = 3; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--seconds") budget = std::stod(argv[i + 1]);
    else if (a == "--seed") seed = std::stoull(argv[i + 1]);
    else if (a == "--case-seconds") case_seconds = std::stod(argv[i + 1]);
    else if (a == "--max-cases") max_cases = std::stol(argv[i + 1]);
  }
  fs::create_directories(out);
  const std::vector<Seed> all = seeds(samples);
  std::mt19937_64 rng(seed);
  std::map<std::string, std::map<std::string, int>> counts;  // format -> outcome -> cases
  int failures = 0, cases = 0;
  const auto t0 = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  while (elapsed() < budget && (max_cases < 0 || cases < max_cases)) {
    const Seed& s = all[rng() % all.size()];
    std::string text;
    if (s.format == "step") {
      text = mutate_step(s.text, rng);
    } else {
      json j = json::parse(s.text);
      const int n = 1 + static_cast<int>(rng() % 3);
      for (int k = 0; k < n; ++k) mutate(j, rng);
      text = quick(s.format, j);
    }
    ++cases;
    const std::string tmp = (out / ("case-" + std::to_string(::getpid()))).string();
    fs::create_directories(tmp);
    const pid_t child = ::fork();
    if (child == 0) {
      ::alarm(static_cast<unsigned>(std::ceil(case_seconds)));  // SIGALRM: counted as slow
      const int null = ::open("/dev/null", O_WRONLY);  // the entries' (and OCCT's) own output
      if (null >= 0) ::dup2(null, 1);
      ::_exit(run_case(s.format, text, s.part, tmp));
    }
    int status = 0;
    ::waitpid(child, &status, 0);
    fs::remove_all(tmp);
    std::string outcome;
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0) outcome = "handled";
    else if (WIFSIGNALED(status) && WTERMSIG(status) == SIGALRM) outcome = "slow";
    else outcome = WIFSIGNALED(status) ? "crash (signal " + std::to_string(WTERMSIG(status)) + ")" : "internal error";
    ++counts[s.format][outcome];
    if (outcome != "handled" && outcome != "slow") {
      ++failures;
      const fs::path saved = out / ("failure-" + std::to_string(failures) + "-" + s.format + (s.format == "step" ? ".step" : ".json"));
      std::ofstream(saved) << text;
      std::cerr << "FAILURE " << outcome << ": " << s.format << " case saved as " << saved
                << " (replay: fuzz_inputs --replay " << s.format << " " << saved << (s.part.empty() ? "" : " " + s.part) << ")\n";
    }
  }
  json summary{{"seed", seed}, {"seconds", elapsed()}, {"cases", cases}, {"failures", failures}, {"by_format", counts}};
  std::cout << summary.dump(2) << "\n";
  std::ofstream(out / "summary.json") << summary.dump(2) << "\n";
  return failures == 0 ? 0 : 1;
}
