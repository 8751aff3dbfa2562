#include "strips/revolution_surface.h"

#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "common/error.h"

namespace parafab {

namespace {

struct MeridianData {
  double a;
  Vec2 b;
  double x_min;
};

int meridian_rhs(sunrealtype, N_Vector y, N_Vector ydot, void* user) {
  const auto* d = static_cast<const MeridianData*>(user);
  const double* q = N_VGetArrayPointer(y);
  double* f = N_VGetArrayPointer(ydot);
  if (!(q[0] > 0)) return 1;  // recoverable: CVODE retries with a smaller step
  f[0] = std::cos(q[2]);
  f[1] = std::sin(q[2]);
  f[2] = (d->a + d->b.x() * q[0] + d->b.y() * q[1]) / q[0];
  return 0;
}

int meridian_root(sunrealtype, N_Vector y, sunrealtype* g, void* user) {
  g[0] = N_VGetArrayPointer(y)[0] - static_cast<const MeridianData*>(user)->x_min;
  return 0;
}

}  // namespace

RevolutionMeridian integrate_revolution_meridian(const RevolutionMeridianOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  PARAFAB_VERIFY(std::isfinite(o.start.x()) && o.start.x() > 0,
                 "meridian.start: the distance x from the axis must be positive, got " << o.start.x());
  PARAFAB_VERIFY(std::isfinite(o.length) && o.length > 0, "meridian.length must be positive, got " << o.length);
  PARAFAB_VERIFY(o.output_points >= 2, "meridian.output_points must be >= 2, got " << o.output_points);
  PARAFAB_VERIFY(std::isfinite(o.a) && std::isfinite(o.b.x()) && std::isfinite(o.b.y()),
                 "meridian: a and b must be finite");
  RevolutionMeridian out;
  MeridianData data{o.a, o.b, o.min_radius * o.length};
  SUNContext ctx = nullptr;
  PARAFAB_VERIFY(SUNContext_Create(nullptr, &ctx) == 0, "CVODE: SUNContext_Create failed");
  N_Vector y = N_VNew_Serial(3, ctx);
  double* q = N_VGetArrayPointer(y);
  q[0] = o.start.x(), q[1] = o.start.y(), q[2] = o.start_angle;
  void* mem = CVodeCreate(CV_ADAMS, ctx);
  SUNNonlinearSolver nls = SUNNonlinSol_FixedPoint(y, 0, ctx);
  int flag = CVodeInit(mem, meridian_rhs, 0.0, y);
  if (flag == CV_SUCCESS) flag = CVodeSStolerances(mem, o.relative_tolerance, o.absolute_tolerance * o.length);
  if (flag == CV_SUCCESS) flag = CVodeSetNonlinearSolver(mem, nls);
  if (flag == CV_SUCCESS) flag = CVodeSetUserData(mem, &data);
  if (flag == CV_SUCCESS) flag = CVodeRootInit(mem, 1, meridian_root);
  if (flag == CV_SUCCESS) flag = CVodeSetMaxNumSteps(mem, 1000000);
  auto record = [&](double s) {
    out.s.push_back(s);
    out.points.emplace_back(q[0], q[1]);
    out.angle.push_back(q[2]);
    out.kappa.push_back((o.a + o.b.x() * q[0] + o.b.y() * q[1]) / q[0]);
  };
  if (flag != CV_SUCCESS) {
    out.message = "CVODE setup failed with flag " + std::to_string(flag);
  } else {
    record(0.0);
    out.complete = true;
    for (int k = 1; k < o.output_points; ++k) {
      const double tout = o.length * k / (o.output_points - 1);
      sunrealtype t = 0;
      flag = CVode(mem, tout, y, &t, CV_NORMAL);
      if (flag == CV_ROOT_RETURN) {
        record(t);
        std::ostringstream os;
        os << "the meridian reaches the axis (x = " << q[0] << ") at s = " << t
           << ": the surface closes there and no strip width ∝ x is admissible beyond";
        out.message = os.str();
        out.complete = false;
        break;
      }
      if (flag < 0) {
        out.message = "CVODE failed with flag " + std::to_string(flag) + " at s = " + std::to_string(t);
        out.complete = false;
        break;
      }
      record(tout);
    }
  }
  out.reached_length = out.s.empty() ? 0 : out.s.back();
  CVodeGetNumSteps(mem, &out.steps);
  CVodeFree(&mem);
  SUNNonlinSolFree(nls);
  N_VDestroy(y);
  SUNContext_Free(&ctx);
  // Residual of the defining equation with κ from finite differences of the output angles
  // (a check of the integration, independent of the right-hand side).
  double scale = 0, res = 0;
  for (size_t k = 1; k + 1 < out.s.size(); ++k) {
    const double kap = (out.angle[k + 1] - out.angle[k - 1]) / (out.s[k + 1] - out.s[k - 1]);
    const double rhs = o.a + o.b.dot(out.points[k]);
    scale = std::max(scale, std::abs(rhs));
    res = std::max(res, std::abs(out.points[k].x() * kap - rhs));
  }
  out.residual = scale > 0 ? res / scale : res;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

RevolutionStrips revolution_strips(const RevolutionMeridian& m, const RevolutionStripsOptions& o) {
  PARAFAB_VERIFY(o.strips >= 3, "revolution.strips must be >= 3, got " << o.strips);
  PARAFAB_VERIFY(o.youngs_modulus > 0 && o.thickness > 0,
                 "revolution: material.E and material.thickness must be positive");
  PARAFAB_VERIFY(m.s.size() >= 2, "revolution: the meridian has fewer than 2 points");
  RevolutionStrips r;
  r.count = o.strips;
  r.s = m.s;
  const double f = 2 * std::tan(M_PI / o.strips), h3 = std::pow(o.thickness, 3);
  double wmin = INFINITY, wmax = 0;
  for (const auto& p : m.points) {
    const double w = f * p.x();
    r.width.push_back(w);
    r.bending_stiffness.push_back(o.youngs_modulus * w * h3 / 12);
    wmin = std::min(wmin, w), wmax = std::max(wmax, w);
  }
  r.R = wmax / wmin;
  for (size_t i = 0; i < r.s.size(); ++i) r.outline.emplace_back(r.s[i], -0.5 * r.width[i]);
  for (size_t i = r.s.size(); i-- > 0;) r.outline.emplace_back(r.s[i], 0.5 * r.width[i]);
  return r;
}

}  // namespace parafab
