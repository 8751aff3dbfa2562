#include "rods/parallel_curve.h"

#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>

#include "common/error.h"

namespace parafab {

namespace {

struct OdeData {
  const std::function<double(double)>* kappa;
  Vec3 c, cb;
};

// y = (γ, γ'); y' = (γ', m (h × γ')), h = c×γ + c̄, m = κ/|h|.
int rhs(sunrealtype s, N_Vector y, N_Vector ydot, void* user) {
  const OdeData& d = *static_cast<const OdeData*>(user);
  const double* v = N_VGetArrayPointer(y);
  double* o = N_VGetArrayPointer(ydot);
  const Vec3 g(v[0], v[1], v[2]), t(v[3], v[4], v[5]);
  const Vec3 h = d.c.cross(g) + d.cb;
  const double hn = h.norm();
  if (!(hn > 0)) return -1;
  const Vec3 a = (*d.kappa)(s) / hn * h.cross(t);
  for (int k = 0; k < 3; ++k) o[k] = t(k), o[3 + k] = a(k);
  return 0;
}

}  // namespace

ParallelCurveResult generate_parallel_curve(const std::function<double(double)>& kappa,
                                            double length, int count,
                                            const ParallelCurveOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  PARAFAB_VERIFY(kappa, "parallel curve: no curvature function");
  if (!(length > 0)) PARAFAB_INPUT_ERROR("parallel curve: length must be > 0, got " << length);
  if (count < 2) PARAFAB_INPUT_ERROR("parallel curve: count must be >= 2, got " << count);
  if (!(options.r > 0)) PARAFAB_INPUT_ERROR("parallel curve: r must be > 0, got " << options.r);
  for (int i = 0; i <= 200; ++i) {
    const double s = length * i / 200, k = kappa(s);
    if (!(k > 0) || !std::isfinite(k))
      PARAFAB_INPUT_ERROR("parallel curve: kappa(s) must be positive, got " << k << " at s = " << s);
  }
  ParallelCurveResult out;
  OdeData data{&kappa, Vec3::UnitZ(), options.p * Vec3::UnitZ()};
  out.c = data.c, out.c_bar = data.cb;
  const Vec3 axis = Vec3(0, options.r, options.p).normalized();
  const Vec3 g0 = options.r * Vec3::UnitX();
  const Vec3 t0v = Eigen::AngleAxisd(options.alpha, axis) * Vec3::UnitX();

  SUNContext ctx = nullptr;
  if (SUNContext_Create(nullptr, &ctx) != 0) {
    out.message = "SUNContext_Create failed";
    return out;
  }
  N_Vector y = N_VNew_Serial(6, ctx);
  double* yv = N_VGetArrayPointer(y);
  for (int k = 0; k < 3; ++k) yv[k] = g0(k), yv[3 + k] = t0v(k);
  void* mem = CVodeCreate(CV_BDF, ctx);
  SUNMatrix A = SUNDenseMatrix(6, 6, ctx);
  SUNLinearSolver LS = SUNLinSol_Dense(y, A, ctx);
  bool ok = mem && A && LS && CVodeInit(mem, rhs, 0.0, y) == CV_SUCCESS &&
            CVodeSStolerances(mem, options.relative_tolerance, options.absolute_tolerance) == CV_SUCCESS &&
            CVodeSetUserData(mem, &data) == CV_SUCCESS &&
            CVodeSetLinearSolver(mem, LS, A) == CV_SUCCESS &&
            CVodeSetMaxNumSteps(mem, 1000000) == CV_SUCCESS;
  auto make_sample = [&](double s, const double* v) {
    RodSample p;
    p.t = s, p.s = s;
    const Vec3 g(v[0], v[1], v[2]);
    Vec3 t(v[3], v[4], v[5]);
    t.normalize();
    const Vec3 h = data.c.cross(g) + data.cb;
    const double hn = h.norm(), k = kappa(s);
    const Vec3 a = k / hn * h.cross(t);  // γ''
    // γ''' = m' h×γ' + m (c×γ')×γ' + m h×γ'', m = κ/|h|.
    const double dk = (kappa(std::min(length, s + 1e-6 * length)) - kappa(std::max(0.0, s - 1e-6 * length))) /
                      (std::min(length, s + 1e-6 * length) - std::max(0.0, s - 1e-6 * length));
    const double dh = h.dot(data.c.cross(t)) / hn;
    const double m = k / hn, dm = dk / hn - k * dh / (hn * hn);
    const Vec3 a3 = dm * h.cross(t) + m * data.c.cross(t).cross(t) + m * h.cross(a);
    p.point = g, p.tangent = t, p.kappa = a.norm();
    p.normal = a / p.kappa;
    p.binormal = t.cross(p.normal);
    const Vec3 w = t.cross(a);
    p.torsion = w.dot(a3) / w.squaredNorm();
    return p;
  };
  if (ok) {
    out.samples.push_back(make_sample(0.0, yv));
    for (int i = 1; i < count && ok; ++i) {
      const double s = length * i / (count - 1);
      sunrealtype tret = 0;
      const int flag = CVode(mem, s, y, &tret, CV_NORMAL);
      if (flag < 0) {
        ok = false;
        out.message = "CVODE failed with flag " + std::to_string(flag) + " at s = " + std::to_string(tret);
        break;
      }
      out.samples.push_back(make_sample(s, N_VGetArrayPointer(y)));
    }
    long nst = 0;
    CVodeGetNumSteps(mem, &nst);
    out.steps = nst;
  } else if (out.message.empty()) {
    out.message = "CVODE setup failed";
  }
  if (mem) CVodeFree(&mem);
  if (LS) SUNLinSolFree(LS);
  if (A) SUNMatDestroy(A);
  N_VDestroy(y);
  SUNContext_Free(&ctx);
  out.status = ok ? ParallelCurveStatus::Ok : ParallelCurveStatus::IntegrationFailed;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace parafab
