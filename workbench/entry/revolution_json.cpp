#include "revolution_json.h"

#include <cmath>

#include "common/error.h"
#include "request_schema.h"
#include "strips/revolution_surface.h"

namespace parafab::entry {

using nlohmann::json;

namespace {

double num(const json& j, const char* key, double fallback, const std::string& path) {
  if (!j.contains(key)) return fallback;
  if (!j[key].is_number()) PARAFAB_INPUT_ERROR(path << " must be a number, got " << j[key].dump());
  return j[key].get<double>();
}

Vec2 vec2(const json& j, const char* key, Vec2 fallback, const std::string& path) {
  if (!j.contains(key)) return fallback;
  const json& v = j[key];
  if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number())
    PARAFAB_INPUT_ERROR(path << " must be [x, y], got " << v.dump());
  return Vec2(v[0].get<double>(), v[1].get<double>());
}

json points(const std::vector<Vec2>& p) {
  json out = json::array();
  for (const Vec2& x : p) out.push_back({x.x(), x.y()});
  return out;
}

}  // namespace

json revolution_strips_json(const json& job) {
  schema::check(job, schema::Format::Revolution);
  RevolutionMeridianOptions mo;
  mo.a = num(job, "a", 0.0, "a");
  mo.b = vec2(job, "b", mo.b, "b");
  mo.start = vec2(job, "start", mo.start, "start");
  mo.start_angle = num(job, "start_angle_deg", 90.0, "start_angle_deg") * M_PI / 180.0;
  mo.length = num(job, "length", 1.0, "length");
  if (job.contains("points") && (!job["points"].is_number_integer() || job["points"].get<int>() < 2))
    PARAFAB_INPUT_ERROR("points must be an integer >= 2, got " << job["points"].dump());
  mo.output_points = job.value("points", 401);
  if (!(mo.start.x() > 0)) PARAFAB_INPUT_ERROR("start[0] is the distance from the axis and must be positive, got " << mo.start.x());
  if (!(mo.length > 0)) PARAFAB_INPUT_ERROR("length must be positive (metres), got " << mo.length);
  RevolutionStripsOptions so;
  if (job.contains("strips") && (!job["strips"].is_number_integer() || job["strips"].get<int>() < 3))
    PARAFAB_INPUT_ERROR("strips must be an integer >= 3, got " << job["strips"].dump());
  so.strips = job.value("strips", 12);
  const json material = job.value("material", json::object());
  so.youngs_modulus = num(material, "E", so.youngs_modulus, "material.E");
  so.thickness = num(material, "thickness", so.thickness, "material.thickness");
  if (!(so.youngs_modulus > 0)) PARAFAB_INPUT_ERROR("material.E must be positive, got " << so.youngs_modulus);
  if (!(so.thickness > 0)) PARAFAB_INPUT_ERROR("material.thickness must be positive (metres), got " << so.thickness);

  const RevolutionMeridian m = integrate_revolution_meridian(mo);
  const RevolutionStrips st = revolution_strips(m, so);
  return {{"meridian", {{"complete", m.complete}, {"reached_length", m.reached_length}, {"s", m.s},
                        {"points", points(m.points)}, {"angle", m.angle}, {"curvature", m.kappa},
                        {"residual", m.residual}, {"steps", m.steps}, {"seconds", m.seconds},
                        {"message", m.message}}},
          {"strips", {{"count", st.count}, {"s", st.s}, {"width", st.width},
                      {"bending_stiffness", st.bending_stiffness}, {"R", st.R}, {"outline", points(st.outline)}}},
          {"units", "m"}};
}

}  // namespace parafab::entry
