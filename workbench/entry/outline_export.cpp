#include "outline_export.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <vector>

#include "common/error.h"
#include "output_files.h"

namespace parafab::entry {

using nlohmann::json;

namespace {

struct P {
  double x, y;  // mm
};
struct Polygon {
  std::string layer;
  std::vector<P> pts;
};
struct Line {
  std::string layer;
  P a, b;
};
struct Text {
  std::string layer;
  P at;
  double height;  // mm
  std::string text;
};
struct Sheet {
  std::string name;
  std::vector<Polygon> polygons;
  std::vector<Line> lines;
  std::vector<Text> texts;
  double xmin = 0, xmax = 0, ymin = 0, ymax = 0;
};

constexpr double kMm = 1000.0;

std::string fmt(double v, int digits = 6) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

const json& field(const json& r, const char* key) {
  auto it = r.find(key);
  if (it == r.end() || it->is_null())
    PARAFAB_INPUT_ERROR("strip result has no " << key << " (export needs a feasible design result)");
  return *it;
}

std::vector<double> nums(const json& v, const char* key) {
  if (!v.is_array()) PARAFAB_INPUT_ERROR("strip result: " << key << " must be an array");
  std::vector<double> out;
  for (const auto& x : v) {
    if (!x.is_number()) PARAFAB_INPUT_ERROR("strip result: " << key << " must hold numbers");
    out.push_back(x.get<double>());
  }
  return out;
}

// A polygon symmetric about the centreline: lower side forward, upper side back (as "outline").
Polygon band(const std::string& layer, const std::vector<double>& s, const std::vector<double>& w) {
  Polygon p{layer, {}};
  for (size_t i = 0; i < s.size(); ++i) p.pts.push_back({s[i] * kMm, -0.5 * w[i] * kMm});
  for (size_t i = s.size(); i-- > 0;) p.pts.push_back({s[i] * kMm, 0.5 * w[i] * kMm});
  return p;
}

Sheet build(const json& r) {
  if (!r.is_object()) PARAFAB_INPUT_ERROR("strip result must be a JSON object");
  if (r.contains("error")) PARAFAB_INPUT_ERROR("strip result is an error: " << r["error"].dump());
  if (!r.value("feasible", false))
    PARAFAB_INPUT_ERROR("strip result is infeasible (" << r.value("reason", std::string()) << "): no outline to export");
  Sheet sh;
  sh.name = r.contains("name") && r["name"].is_string() ? r["name"].get<std::string>() : "strip";
  const std::vector<double> s = nums(field(r, "s"), "s"), w = nums(field(r, "width"), "width");
  if (s.size() != w.size() || s.size() < 2) PARAFAB_INPUT_ERROR("strip result: s and width must have equal lengths >= 2");
  const double length = field(r, "length").get<double>();
  double wmax = *std::max_element(w.begin(), w.end());

  const json* comp = r.contains("composite") && !r["composite"].is_null() ? &r["composite"] : nullptr;
  if (comp && (*comp).value("feasible", false)) {
    const double w1 = (*comp)["outer_width"].get<double>();
    sh.polygons.push_back(band("OUTER", s, std::vector<double>(s.size(), w1)));
    sh.polygons.push_back(band("INNER", s, nums((*comp)["w2"], "composite.w2")));
    wmax = std::max(wmax, w1);
  } else {
    const json& outline = field(r, "outline");
    Polygon p{"OUTLINE", {}};
    for (const auto& q : outline) p.pts.push_back({q[0].get<double>() * kMm, q[1].get<double>() * kMm});
    // A perforated strip is cut at its outer width; the solid width is what the holes leave.
    if (r.contains("perforations") && !r["perforations"].is_null() && r["perforations"].value("feasible", false)) {
      const double wo = r["perforations"]["outer_width"].get<double>();
      p = band("OUTLINE", s, std::vector<double>(s.size(), wo));
      wmax = std::max(wmax, wo);
      for (const auto& d : r["perforations"]["diamonds"]) {
        Polygon h{"HOLES", {}};
        for (const auto& c : d["corners"]) h.pts.push_back({c[0].get<double>() * kMm, c[1].get<double>() * kMm});
        sh.polygons.push_back(h);
      }
    }
    sh.polygons.insert(sh.polygons.begin(), p);
  }

  // Clamps and end angles.
  const double half = 0.5 * wmax * kMm, th = std::max(2.0, std::min(6.0, 0.25 * wmax * kMm));
  std::vector<json> ends;
  if (r.contains("ends") && r["ends"].is_array()) ends.assign(r["ends"].begin(), r["ends"].end());
  for (int e = 0; e < 2; ++e) {
    const double x = e == 0 ? 0.0 : length * kMm;
    sh.lines.push_back({"CLAMPS", {x, -half - 2.0}, {x, half + 2.0}});
    std::ostringstream t;
    t << (e == 0 ? "START" : "END");
    std::string kind = "clamp";
    double angle = NAN;
    if (e < static_cast<int>(ends.size())) {
      const json& en = ends[e];
      if (en.value("free_angle", false)) kind = "pin";
      if (en.value("free_x", false) || en.value("free_y", false)) kind += " (sliding)";
      if (en.contains("angle_deg") && en["angle_deg"].is_number()) angle = en["angle_deg"].get<double>();
    }
    t << " " << kind << " s=" << fmt(x, 2) << " mm";
    if (std::isfinite(angle)) t << " angle=" << fmt(angle, 2) << " deg";
    sh.texts.push_back({"TEXT", {e == 0 ? x : x, -half - 2.0 - 1.4 * th * (e == 0 ? 1 : 2)}, 0.7 * th, t.str()});
  }
  std::ostringstream name;
  name << sh.name << "  L=" << fmt(length * kMm, 2) << " mm";
  if (r.contains("thickness") && r["thickness"].is_number()) name << "  h=" << fmt(r["thickness"].get<double>() * kMm, 3) << " mm";
  if (r.contains("R") && r["R"].is_number()) name << "  R=" << fmt(r["R"].get<double>(), 4);
  sh.texts.push_back({"TEXT", {0.0, half + 2.0 + 0.5 * th}, th, name.str()});

  sh.xmin = -5.0, sh.xmax = length * kMm + 5.0;
  sh.ymin = -half - 2.0 - 1.4 * th * 2 - th, sh.ymax = half + 2.0 + 2.0 * th;
  // Texts may be longer than the strip: widen the page (approximate glyph width 0.6·height).
  for (const auto& t : sh.texts) sh.xmax = std::max(sh.xmax, t.at.x + 0.6 * t.height * t.text.size() + 2.0);
  return sh;
}

void pair(std::ostream& os, int code, const std::string& v) { os << code << "\n" << v << "\n"; }

std::string xml_escape(const std::string& in) {
  std::string out;
  for (char c : in) {
    if (c == '&') out += "&amp;";
    else if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else if (c == '"') out += "&quot;";
    else out += c;
  }
  return out;
}

}  // namespace

std::string strip_outline_dxf(const json& result) {
  const Sheet sh = build(result);
  std::ostringstream os;
  pair(os, 999, "ParaFab strip cut sheet, millimetres");
  pair(os, 0, "SECTION");
  pair(os, 2, "HEADER");
  pair(os, 9, "$ACADVER");
  pair(os, 1, "AC1009");
  pair(os, 9, "$INSUNITS");
  pair(os, 70, "4");
  pair(os, 9, "$EXTMIN");
  pair(os, 10, fmt(sh.xmin)); pair(os, 20, fmt(sh.ymin));
  pair(os, 9, "$EXTMAX");
  pair(os, 10, fmt(sh.xmax)); pair(os, 20, fmt(sh.ymax));
  pair(os, 0, "ENDSEC");
  const std::vector<std::pair<std::string, int>> layers = {
      {"OUTLINE", 1}, {"OUTER", 1}, {"INNER", 5}, {"HOLES", 1}, {"CLAMPS", 3}, {"TEXT", 7}};
  pair(os, 0, "SECTION");
  pair(os, 2, "TABLES");
  pair(os, 0, "TABLE");
  pair(os, 2, "LAYER");
  pair(os, 70, std::to_string(layers.size()));
  for (const auto& [n, color] : layers) {
    pair(os, 0, "LAYER");
    pair(os, 2, n);
    pair(os, 70, "0");
    pair(os, 62, std::to_string(color));
    pair(os, 6, "CONTINUOUS");
  }
  pair(os, 0, "ENDTAB");
  pair(os, 0, "ENDSEC");
  pair(os, 0, "SECTION");
  pair(os, 2, "ENTITIES");
  for (const auto& p : sh.polygons) {
    pair(os, 0, "POLYLINE");
    pair(os, 8, p.layer);
    pair(os, 66, "1");
    pair(os, 10, "0.0"); pair(os, 20, "0.0"); pair(os, 30, "0.0");
    pair(os, 70, "1");  // closed
    for (const auto& q : p.pts) {
      pair(os, 0, "VERTEX");
      pair(os, 8, p.layer);
      pair(os, 10, fmt(q.x, 9));
      pair(os, 20, fmt(q.y, 9));
      pair(os, 30, "0.0");
    }
    pair(os, 0, "SEQEND");
    pair(os, 8, p.layer);
  }
  for (const auto& l : sh.lines) {
    pair(os, 0, "LINE");
    pair(os, 8, l.layer);
    pair(os, 10, fmt(l.a.x)); pair(os, 20, fmt(l.a.y)); pair(os, 30, "0.0");
    pair(os, 11, fmt(l.b.x)); pair(os, 21, fmt(l.b.y)); pair(os, 31, "0.0");
  }
  for (const auto& t : sh.texts) {
    pair(os, 0, "TEXT");
    pair(os, 8, t.layer);
    pair(os, 10, fmt(t.at.x)); pair(os, 20, fmt(t.at.y)); pair(os, 30, "0.0");
    pair(os, 40, fmt(t.height, 3));
    pair(os, 1, t.text);
  }
  pair(os, 0, "ENDSEC");
  pair(os, 0, "EOF");
  return os.str();
}

std::string strip_outline_svg(const json& result) {
  const Sheet sh = build(result);
  const double W = sh.xmax - sh.xmin, H = sh.ymax - sh.ymin;
  std::ostringstream os;
  // SVG y points down: the sheet is mirrored (y_svg = −y), so the viewBox starts at −ymax.
  os << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
     << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << fmt(W, 3) << "mm\" height=\"" << fmt(H, 3)
     << "mm\" viewBox=\"" << fmt(sh.xmin, 3) << " " << fmt(-sh.ymax, 3) << " " << fmt(W, 3) << " " << fmt(H, 3)
     << "\">\n";
  os << "<title>" << xml_escape(sh.name) << "</title>\n";
  os << "<desc>ParaFab strip cut sheet; user units are millimetres, y mirrored (svg y = -y)</desc>\n";
  auto color = [](const std::string& layer) {
    if (layer == "INNER") return "blue";
    if (layer == "CLAMPS") return "green";
    if (layer == "TEXT") return "black";
    return "red";
  };
  for (const char* layer : {"OUTLINE", "OUTER", "INNER", "HOLES"}) {
    bool any = false;
    for (const auto& p : sh.polygons) any |= p.layer == layer;
    if (!any) continue;
    os << "<g id=\"" << layer << "\" fill=\"none\" stroke=\"" << color(layer) << "\" stroke-width=\"0.1\">\n";
    for (const auto& p : sh.polygons) {
      if (p.layer != layer) continue;
      os << "<polygon class=\"" << layer << "\" points=\"";
      for (size_t i = 0; i < p.pts.size(); ++i)
        os << (i ? " " : "") << fmt(p.pts[i].x, 9) << "," << fmt(-p.pts[i].y, 9);
      os << "\"/>\n";
    }
    os << "</g>\n";
  }
  os << "<g id=\"CLAMPS\" stroke=\"green\" stroke-width=\"0.2\">\n";
  for (const auto& l : sh.lines)
    os << "<line x1=\"" << fmt(l.a.x) << "\" y1=\"" << fmt(-l.a.y) << "\" x2=\"" << fmt(l.b.x) << "\" y2=\""
       << fmt(-l.b.y) << "\"/>\n";
  os << "</g>\n<g id=\"TEXT\" fill=\"black\" font-family=\"sans-serif\">\n";
  for (const auto& t : sh.texts)
    os << "<text x=\"" << fmt(t.at.x) << "\" y=\"" << fmt(-t.at.y) << "\" font-size=\"" << fmt(t.height, 3)
       << "\">" << xml_escape(t.text) << "</text>\n";
  os << "</g>\n</svg>\n";
  return os.str();
}

void write_strip_outline(const json& result, const std::string& path) {
  std::string ext = path.size() >= 4 ? path.substr(path.size() - 4) : "";
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  std::string text;
  if (ext == ".dxf") text = strip_outline_dxf(result);
  else if (ext == ".svg") text = strip_outline_svg(result);
  else PARAFAB_INPUT_ERROR("outline file " << path << " must end in .dxf or .svg");
  try {
    write_text_atomically(path, text);
  } catch (const Error&) {
    PARAFAB_INPUT_ERROR("cannot write outline file " << path);
  }
}

}  // namespace parafab::entry
