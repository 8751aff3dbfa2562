// JSON of a part's face model (thesis §6.2.1, §6.5.1) for `parafab inspect`. Parameter names
// follow the relation equations: plane p, n; cylinder c, d, r; cone c, d, r, a; sphere c, d, r;
// torus c, d, R, r; plus x, the direction of u = 0.
#include "part_json.h"
#include "json_write.h"

namespace parafab::entry {

using nlohmann::json;

namespace {

json vec(const Eigen::Vector3d& v) { return json_write::coordinates(v); }

json parameters(const occ::Primitive& p) {
  using T = occ::SurfaceType;
  switch (p.type) {
    case T::plane: return {{"p", vec(p.location)}, {"n", vec(p.axis)}, {"x", vec(p.x_direction)}};
    case T::cylinder:
    case T::cone:
    case T::sphere:
    case T::torus: {
      json j = {{"c", vec(p.location)}, {"d", vec(p.axis)}, {"x", vec(p.x_direction)}, {"r", p.radius}};
      if (p.type == T::cone) j["a"] = p.semi_angle;
      if (p.type == T::torus) j["R"] = p.major_radius;
      return j;
    }
    case T::revolution: return {{"c", vec(p.location)}, {"d", vec(p.axis)}};
    case T::extrusion: return {{"d", vec(p.axis)}};
    case T::offset: return {{"offset", p.offset}};
    default: return json::object();
  }
}

json nurbs(const occ::NurbsSurface& s) {
  json poles = json::array();
  for (const auto& q : s.poles) poles.push_back({q[0], q[1], q[2], q[3]});
  return {{"degree", {s.degree_u, s.degree_v}},
          {"count", {s.count_u, s.count_v}},
          {"knots_u", s.knots_u},
          {"knots_v", s.knots_v},
          {"poles", poles}};
}

json face(const occ::FaceInfo& f) {
  json loops = json::array();
  for (const auto& l : f.loops) {
    json uv = json::array();
    for (const auto& p : l.uv) uv.push_back({p.x(), p.y()});
    loops.push_back({{"outer", l.outer}, {"edges", l.edges}, {"uv", uv}});
  }
  json j = {{"index", f.index},         {"type", occ::to_string(f.primitive.type)},
            {"reversed", f.reversed},   {"area", f.area},
            {"uv_bounds", f.uv_bounds}, {"parameters", parameters(f.primitive)},
            {"nurbs", nurbs(f.nurbs)},  {"loops", loops}};
  // A B-spline face: its poles are shape parameters "pole i j x|y|z" (1-based; periodic: the distinct ones).
  if (f.bspline.count_u > 0) j["pole_count"] = {f.bspline.distinct_u(), f.bspline.distinct_v()};
  return j;
}

}  // namespace

json inspect_part_json(const std::string& path, const InspectOptions& options) {
  occ::ReadOptions read = options.read;
  read.check_self_intersection = true;  // inspect is the check of a part: the thorough one
  const auto part = occ::read_part(path, read);
  const occ::PartInfo info = occ::part_info(*part);
  const occ::FaceModel model = occ::build_face_model(*part, options.model);
  json faces = json::array(), edges = json::array(), relations = json::array();
  for (const auto& f : model.faces) faces.push_back(face(f));
  for (const auto& e : model.edges)
    edges.push_back({{"index", e.index},
                     {"faces", e.faces},
                     {"seam", e.seam},
                     {"degenerated", e.degenerated},
                     {"continuity", e.continuity},
                     {"max_angle_deg", e.max_angle_deg},
                     {"tangent", e.tangent}});
  for (const auto& r : model.relations) {
    json samples = json::array();
    for (const auto& s : r.samples) samples.push_back({{s[0].x(), s[0].y()}, {s[1].x(), s[1].y()}});
    json j = {{"kind", r.kind}, {"faces", r.faces},         {"edges", r.edges},
              {"sign", r.sign}, {"equations", r.equations}, {"residuals", r.residuals}};
    if (!samples.empty()) j["samples"] = samples;
    relations.push_back(j);
  }
  return {{"source", info.source},
          {"solid", {{"index", info.solid_index}, {"count", info.solid_count}, {"name", info.name}}},
          {"bbox", {{"min", vec(info.bbox_min)}, {"max", vec(info.bbox_max)}}},
          {"volume", info.volume},
          {"area", info.area},
          {"faces", faces},
          {"edges", edges},
          {"relations", relations}};
}

}  // namespace parafab::entry
