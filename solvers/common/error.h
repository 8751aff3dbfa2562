// ParaFab errors: invalid input throws parafab::Error with a message that names the
// input and the offending value; solver non-convergence is a Result status instead.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace parafab {

/// Invalid input or a violated precondition. `what()` names the problem and where it is.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The caller stopped the run (a progress callback returned false): not an input error, though
/// caught as one where that is all a caller distinguishes. Python: parafab.Cancelled.
class Cancelled : public Error {
 public:
  using Error::Error;
};

namespace detail {
[[noreturn]] inline void fail(const char* file, int line, const std::string& message) {
  std::ostringstream os;
  os << message << " [" << file << ":" << line << "]";
  throw Error(os.str());
}
}  // namespace detail

}  // namespace parafab

/// Always-on check (also in Release builds): throws parafab::Error with `message`
/// (a stream expression, e.g. "thickness must be > 0, got " << h) and the source location.
#define PARAFAB_VERIFY(cond, message)                                   \
  do {                                                                  \
    if (!(cond)) {                                                      \
      std::ostringstream parafab_verify_os_;                            \
      parafab_verify_os_ << message;                                    \
      ::parafab::detail::fail(__FILE__, __LINE__, parafab_verify_os_.str()); \
    }                                                                   \
  } while (0)

/// Throws parafab::Error with `message` without the source location: for input errors
/// whose message already says exactly where the problem is (e.g. "curve.points[3]").
#define PARAFAB_INPUT_ERROR(message)                \
  do {                                              \
    std::ostringstream parafab_input_os_;           \
    parafab_input_os_ << message;                   \
    throw ::parafab::Error(parafab_input_os_.str()); \
  } while (0)
