// Reads STEP/BREP parts, selects one solid and validates it (closed, manifold, BRepCheck):
// the B-rep input of X-CAD (thesis §6.2.1).
#include "part_reader.h"

#include <BRepBndLib.hxx>
#include <BRepBuilderAPI_Transform.hxx>
#include <BOPAlgo_CheckResult.hxx>
#include <BRepAlgoAPI_Check.hxx>
#include <BRepCheck.hxx>
#include <BRepCheck_Analyzer.hxx>
#include <BRepCheck_Result.hxx>
#include <BRepGProp.hxx>
#include <gp_Ax1.hxx>
#include <gp_Trsf.hxx>
#include <gp_Vec.hxx>
#include <BRepTools.hxx>
#include <BRep_Builder.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <GProp_GProps.hxx>
#include <Interface_Check.hxx>
#include <Interface_CheckIterator.hxx>
#include <Interface_InterfaceModel.hxx>
#include <STEPControl_Reader.hxx>
#include <mutex>
#include <TCollection_HAsciiString.hxx>
#include <XSControl_WorkSession.hxx>
#include <Standard_Failure.hxx>
#include <StepBasic_Product.hxx>
#include <StepBasic_ProductDefinition.hxx>
#include <StepBasic_ProductDefinitionFormation.hxx>
#include <StepShape_ManifoldSolidBrep.hxx>
#include <TCollection_HAsciiString.hxx>
#include <TopExp.hxx>
#include <TopoDS_Vertex.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_IndexedDataMapOfShapeListOfShape.hxx>
#include <TransferBRep.hxx>
#include <Transfer_TransientProcess.hxx>
#include <XSControl_TransferReader.hxx>
#include <XSControl_WorkSession.hxx>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>

#include "common/error.h"
#include "occt_shape.h"

namespace parafab::occ {

namespace {

enum class Format { step, brep, unknown };

Format sniff(const std::string& head) {
  const size_t start = head.find_first_not_of(" \t\r\n\xEF\xBB\xBF");
  if (start != std::string::npos && head.compare(start, 12, "ISO-10303-21") == 0) return Format::step;
  if (head.find("CASCADE Topology") != std::string::npos) return Format::brep;
  return Format::unknown;
}

std::string failure_text(const Standard_Failure& e) {
  const char* m = e.GetMessageString();
  return std::string(e.DynamicType()->Name()) + (m && *m ? std::string(": ") + m : "");
}

std::string text(const Handle(TCollection_HAsciiString) & s) { return s.IsNull() ? "" : s->ToCString(); }

// Names of `solids` in a STEP file: the solid entity's own name if set, else the name of the
// innermost product whose shape contains it. Matched by TShape (instances carry locations).
std::vector<std::string> step_solid_names(const STEPControl_Reader& reader,
                                          const TopTools_IndexedMapOfShape& solids) {
  const int n = solids.Extent();
  std::vector<std::string> entity(n), product(n);
  std::vector<int> product_size(n, std::numeric_limits<int>::max());
  const Handle(Transfer_TransientProcess) tp = reader.WS()->TransferReader()->TransientProcess();
  const Handle(Interface_InterfaceModel) model = reader.Model();
  for (int k = 1; k <= model->NbEntities(); ++k) {
    const Handle(Standard_Transient) ent = model->Value(k);
    const auto brep = Handle(StepShape_ManifoldSolidBrep)::DownCast(ent);
    const auto pd = Handle(StepBasic_ProductDefinition)::DownCast(ent);
    std::string name;
    if (!brep.IsNull())
      name = text(brep->Name());
    else if (!pd.IsNull() && !pd->Formation().IsNull() && !pd->Formation()->OfProduct().IsNull())
      name = text(pd->Formation()->OfProduct()->Name());
    if (name.empty()) continue;
    const TopoDS_Shape result = TransferBRep::ShapeResult(tp, ent);
    if (result.IsNull()) continue;
    TopTools_IndexedMapOfShape inside;
    TopExp::MapShapes(result, TopAbs_SOLID, inside);
    for (int j = 1; j <= inside.Extent(); ++j)
      for (int i = 0; i < n; ++i) {
        if (solids(i + 1).TShape() != inside(j).TShape()) continue;
        if (!brep.IsNull())
          entity[i] = name;
        else if (inside.Extent() <= product_size[i])
          product[i] = name, product_size[i] = inside.Extent();
      }
  }
  for (int i = 0; i < n; ++i)
    if (entity[i].empty()) entity[i] = product[i];
  return entity;
}

std::string list_solids(const std::vector<std::string>& names, int count) {
  std::ostringstream os;
  for (int i = 0; i < count; ++i) {
    os << (i ? ", " : "") << i;
    if (i < static_cast<int>(names.size()) && !names[i].empty()) os << " '" << names[i] << "'";
  }
  return os.str();
}

// Faces of `edge` (distinct), from an edge → faces ancestor map.
int face_count_of(const TopTools_IndexedDataMapOfShapeListOfShape& edge_faces, const TopoDS_Shape& edge,
                  TopTools_IndexedMapOfShape& faces) {
  faces.Clear();
  if (const TopTools_ListOfShape* list = edge_faces.Seek(edge))
    for (const TopoDS_Shape& f : *list) faces.Add(f);
  return faces.Extent();
}

// An edge bounding a single face that is not that face's seam: the shell is open there.
bool is_free_edge(const TopoDS_Edge& e, const TopTools_IndexedMapOfShape& faces) {
  return faces.Extent() == 1 && !BRep_Tool::Degenerated(e) && !BRep_Tool::IsClosed(e, TopoDS::Face(faces(1)));
}

// "open shell: N edges bound only one face, first edge k (face j)", or "" if none.
std::string open_edges(const TopoDS_Shape& shape, const TopTools_IndexedMapOfShape& edges,
                       const TopTools_IndexedMapOfShape& all_faces) {
  TopTools_IndexedDataMapOfShapeListOfShape edge_faces;
  TopExp::MapShapesAndAncestors(shape, TopAbs_EDGE, TopAbs_FACE, edge_faces);
  TopTools_IndexedMapOfShape faces;
  int count = 0, first = -1, first_face = -1;
  for (int i = 1; i <= edges.Extent(); ++i) {
    face_count_of(edge_faces, edges(i), faces);
    if (!is_free_edge(TopoDS::Edge(edges(i)), faces)) continue;
    if (count++ == 0) first = i - 1, first_face = all_faces.FindIndex(faces(1)) - 1;
  }
  if (count == 0) return "";
  std::ostringstream os;
  os << "open shell (not closed): " << count << " edge(s) bound only one face, first edge " << first
     << " of face " << first_face;
  return os.str();
}

std::string status_name(const BRepCheck_ListOfStatus& list) {
  for (BRepCheck_Status s : list)
    if (s != BRepCheck_NoError) {
      std::ostringstream os;
      BRepCheck::Print(s, os);
      std::string t = os.str();
      t.erase(t.find_last_not_of(" \n") + 1);
      return t;
    }
  return "";
}

// First BRepCheck status other than NoError of `sub`, on its own or in a context (an edge in a
// face, a vertex on an edge, ...); "" if none.
std::string check_failure(const BRepCheck_Analyzer& analyzer, const TopoDS_Shape& sub) {
  const Handle(BRepCheck_Result)& r = analyzer.Result(sub);
  if (r.IsNull()) return "";
  std::string t = status_name(r->Status());
  for (r->InitContextIterator(); t.empty() && r->MoreShapeInContext(); r->NextShapeInContext())
    t = status_name(r->StatusOnShape());
  return t;
}

// Names the first failing sub-shape of an invalid solid: faces, edges, vertices, wires, shells.
std::string describe_check_failure(const PartShape& part) {
  const BRepCheck_Analyzer analyzer(part.shape);
  if (analyzer.IsValid()) return "";
  std::ostringstream os;
  for (int i = 0; i < part.face_count(); ++i)
    if (auto t = check_failure(analyzer, part.face(i)); !t.empty())
      return (os << t << " on face " << i, os.str());
  TopTools_IndexedDataMapOfShapeListOfShape edge_faces;
  TopExp::MapShapesAndAncestors(part.shape, TopAbs_EDGE, TopAbs_FACE, edge_faces);
  TopTools_IndexedMapOfShape faces;
  for (int i = 0; i < part.edge_count(); ++i)
    if (auto t = check_failure(analyzer, part.edge(i)); !t.empty()) {
      os << t << " on edge " << i;
      face_count_of(edge_faces, part.edge(i), faces);
      for (int k = 1; k <= faces.Extent(); ++k)
        os << (k == 1 ? " (faces " : ", ") << part.face_index(faces(k));
      return (os << (faces.IsEmpty() ? "" : ")"), os.str());
    }
  for (int i = 1; i <= part.vertices.Extent(); ++i)
    if (auto t = check_failure(analyzer, part.vertices(i)); !t.empty())
      return (os << t << " on vertex " << i - 1, os.str());
  for (int i = 0; i < part.face_count(); ++i)
    for (TopExp_Explorer w(part.face(i), TopAbs_WIRE); w.More(); w.Next())
      if (auto t = check_failure(analyzer, w.Current()); !t.empty())
        return (os << t << " on a wire of face " << i, os.str());
  for (TopExp_Explorer s(part.shape, TopAbs_SHELL); s.More(); s.Next())
    if (auto t = check_failure(analyzer, s.Current()); !t.empty()) return t + " on a shell of the solid";
  const std::string t = check_failure(analyzer, part.shape);
  return t.empty() ? "BRepCheck_Analyzer: invalid (no status names the sub-shape)" : t + " on the solid";
}

// For a part whose coordinates are so large that doubles resolve them to more than 1/1000 of
// its largest vertex tolerance (OCCT's 1e-7 at about 4.5e5): a note naming the distance, since
// BRepCheck's distance checks then fail on round-off alone (issue 56: a box with a hole cut at
// 1e8 mm, valid in memory, fails InvalidPointOnCurve after a BREP write and read). "" otherwise.
std::string far_from_origin(const PartShape& part) {
  Bnd_Box box;
  BRepBndLib::Add(part.shape, box, false);
  if (box.IsVoid()) return "";
  double x0, y0, z0, x1, y1, z1;
  box.Get(x0, y0, z0, x1, y1, z1);
  const double far = std::max({std::abs(x0), std::abs(y0), std::abs(z0), std::abs(x1), std::abs(y1), std::abs(z1)});
  double tolerance = 0;
  for (int i = 1; i <= part.vertices.Extent(); ++i)
    tolerance = std::max(tolerance, BRep_Tool::Tolerance(TopoDS::Vertex(part.vertices(i))));
  const double resolution = far * std::numeric_limits<double>::epsilon();
  if (!(resolution > 1e-3 * tolerance)) return "";
  std::ostringstream os;
  os.precision(3);
  os << " (the part lies " << far << " from the origin, where doubles resolve " << resolution
     << ", against OCCT's tolerance " << tolerance
     << ": its checks may fail on round-off alone; move the part nearer the origin in the CAD system)";
  return os.str();
}

void validate(const PartShape& part) {
  const std::string& src = part.source;
  TopTools_IndexedDataMapOfShapeListOfShape edge_faces;
  TopExp::MapShapesAndAncestors(part.shape, TopAbs_EDGE, TopAbs_FACE, edge_faces);
  TopTools_IndexedMapOfShape faces;
  for (int i = 0; i < part.edge_count(); ++i)
    if (face_count_of(edge_faces, part.edge(i), faces) > 2) {
      std::ostringstream os;
      for (int k = 1; k <= faces.Extent(); ++k) os << (k > 1 ? ", " : "") << part.face_index(faces(k));
      PARAFAB_INPUT_ERROR(src << ": non-manifold solid: edge " << i << " is shared by " << faces.Extent()
                              << " faces (" << os.str() << ")");
    }
  if (const std::string open = open_edges(part.shape, part.edges, part.faces); !open.empty())
    PARAFAB_INPUT_ERROR(src << ": " << open);
  if (const std::string bad = describe_check_failure(part); !bad.empty())
    PARAFAB_INPUT_ERROR(src << ": invalid shape: BRepCheck reports " << bad << far_from_origin(part));
  GProp_GProps props;
  BRepGProp::VolumeProperties(part.shape, props);
  if (!(props.Mass() > 0))
    PARAFAB_INPUT_ERROR(src << ": invalid shape: the solid is inside out or empty (volume " << props.Mass()
                            << ")");
}

void refuse_self_intersection(const PartShape& part) {
  BRepAlgoAPI_Check check(part.shape, /*bTestSE=*/true, /*bTestSI=*/true);
  if (check.IsValid()) return;
  std::ostringstream os;
  for (const BOPAlgo_CheckResult& r : check.Result()) {
    if (r.GetCheckStatus() != BOPAlgo_SelfIntersect && r.GetCheckStatus() != BOPAlgo_BadType) continue;
    std::vector<int> faces;
    for (const TopoDS_Shape& s : r.GetFaultyShapes1())
      for (TopExp_Explorer f(s, TopAbs_FACE); f.More(); f.Next()) faces.push_back(part.face_index(f.Current()));
    os << " faces";
    for (int f : faces) os << " " << f;
    break;
  }
  PARAFAB_INPUT_ERROR(part.source << ": invalid shape: the solid intersects itself (OCCT's Boolean check"
                                  << (os.str().empty() ? "" : ":" + os.str()) << ")");
}

[[noreturn]] void no_solid(const TopoDS_Shape& shape, const std::string& src) {
  TopTools_IndexedMapOfShape faces, edges;
  TopExp::MapShapes(shape, TopAbs_FACE, faces);
  TopExp::MapShapes(shape, TopAbs_EDGE, edges);
  if (faces.IsEmpty()) PARAFAB_INPUT_ERROR(src << ": no solid (the file holds no faces either)");
  const std::string open = open_edges(shape, edges, faces);
  if (!open.empty())
    PARAFAB_INPUT_ERROR(src << ": no solid, only " << faces.Extent() << " face(s) forming an " << open);
  PARAFAB_INPUT_ERROR(src << ": no solid, only a closed shell of " << faces.Extent()
                          << " faces (export it as a solid)");
}

// Captures what OpenCASCADE prints to std::cout while reading (its default message printer
// and the BREP reader write there), so the CLI's stdout stays JSON; errors quote the text.
class CaptureStdout {
 public:
  CaptureStdout() : old_(std::cout.rdbuf(buffer_.rdbuf())) {}
  ~CaptureStdout() { std::cout.rdbuf(old_); }
  CaptureStdout(const CaptureStdout&) = delete;
  CaptureStdout& operator=(const CaptureStdout&) = delete;
  /// ": <text>" with colour codes, '*' frames and runs of white space removed; "" if nothing.
  std::string detail() const {
    std::string out;
    const std::string raw = buffer_.str();
    for (size_t i = 0; i < raw.size(); ++i) {
      if (raw[i] == '\x1b') {
        i = raw.find('m', i);
        if (i == std::string::npos) break;
      } else if (raw[i] == '*' || std::isspace(static_cast<unsigned char>(raw[i]))) {
        if (!out.empty() && out.back() != ' ') out += ' ';
      } else {
        out += raw[i];
      }
    }
    while (!out.empty() && out.back() == ' ') out.pop_back();
    return out.empty() ? "" : ": " + out;
  }

 private:
  std::ostringstream buffer_;
  std::streambuf* old_;
};

// Runs f, turning OpenCASCADE exceptions into parafab::Error naming `what`.
template <class F>
auto guarded(const std::string& what, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const Standard_Failure& e) {
    PARAFAB_INPUT_ERROR(what << ": OpenCASCADE failed: " << failure_text(e));
  }
}

TopoDS_Shape read_brep_stream(std::istream& in, const std::string& src) {
  TopoDS_Shape shape;
  const CaptureStdout log;
  guarded(src + " (reading BREP)", [&] { BRepTools::Read(shape, in, BRep_Builder()); });
  if (shape.IsNull()) PARAFAB_INPUT_ERROR(src << ": unreadable BREP, no shape in it" << log.detail());
  return shape;
}

}  // namespace

std::string check_failure_description(const PartShape& part) { return describe_check_failure(part); }

std::shared_ptr<const PartShape> make_part(const TopoDS_Shape& shape, const std::string& source,
                                           const ReadOptions& options,
                                           const std::vector<std::string>& names) {
  if (shape.IsNull()) PARAFAB_INPUT_ERROR(source << ": no shape");
  TopTools_IndexedMapOfShape solids;
  TopExp::MapShapes(shape, TopAbs_SOLID, solids);
  const int n = solids.Extent();
  if (n == 0 && options.surfaces_allowed) {
    auto surface = std::make_shared<PartShape>();
    surface->shape = shape;
    surface->source = source;
    surface->solid_count = 0;
    TopExp::MapShapes(shape, TopAbs_FACE, surface->faces);
    TopExp::MapShapes(shape, TopAbs_EDGE, surface->edges);
    TopExp::MapShapes(shape, TopAbs_VERTEX, surface->vertices);
    if (surface->faces.IsEmpty()) PARAFAB_INPUT_ERROR(source << ": no faces to take sections of");
    return surface;
  }
  if (n == 0) no_solid(shape, source);
  if (options.solid_index >= 0 && !options.solid_name.empty())
    PARAFAB_INPUT_ERROR(source << ": choose the solid by index or by name, not both");
  int chosen = 0;
  if (options.solid_index >= 0) {
    if (options.solid_index >= n)
      PARAFAB_INPUT_ERROR(source << ": solid_index " << options.solid_index << " is out of range: it holds "
                                 << n << " solid(s) (" << list_solids(names, n) << ")");
    chosen = options.solid_index;
  } else if (!options.solid_name.empty()) {
    chosen = -1;
    for (int i = 0; i < n && i < static_cast<int>(names.size()); ++i)
      if (names[i] == options.solid_name) {
        if (chosen >= 0)
          PARAFAB_INPUT_ERROR(source << ": several solids are named '" << options.solid_name << "' ("
                                     << list_solids(names, n) << "); choose by index");
        chosen = i;
      }
    if (chosen < 0)
      PARAFAB_INPUT_ERROR(source << ": no solid named '" << options.solid_name
                                 << "' (solids: " << list_solids(names, n) << ")");
  } else if (n > 1) {
    PARAFAB_INPUT_ERROR(source << ": " << n << " solids (" << list_solids(names, n)
                               << "); choose one: \"solid\": N in a simulate job, --solid N or --solid-name NAME "
                                  "for inspect, --solid N for integrate, solid_index / solid_name in Python");
  }
  auto part = std::make_shared<PartShape>();
  part->shape = solids(chosen + 1);
  part->source = source;
  part->name = chosen < static_cast<int>(names.size()) ? names[chosen] : "";
  part->solid_index = chosen;
  part->solid_count = n;
  TopExp::MapShapes(part->shape, TopAbs_FACE, part->faces);
  TopExp::MapShapes(part->shape, TopAbs_EDGE, part->edges);
  TopExp::MapShapes(part->shape, TopAbs_VERTEX, part->vertices);
  guarded(source + " (validating the solid)", [&] { validate(*part); });
  if (options.check_self_intersection)
    guarded(source + " (checking self-intersection)", [&] { refuse_self_intersection(*part); });
  return part;
}

std::shared_ptr<const PartShape> read_part(const std::string& path, const ReadOptions& options) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec)) PARAFAB_INPUT_ERROR("part file not found: " << path);
  if (fs::is_directory(path, ec)) PARAFAB_INPUT_ERROR("part file " << path << " is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) PARAFAB_INPUT_ERROR("cannot open part file " << path);
  std::string head(4096, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(in.gcount()));
  if (head.find_first_not_of(" \t\r\n") == std::string::npos && fs::file_size(path, ec) <= head.size())
    PARAFAB_INPUT_ERROR("part file " << path << " is empty");
  const Format format = sniff(head);
  if (format == Format::unknown) {
    std::string ext = fs::path(path).extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    const bool claims = ext == ".step" || ext == ".stp" || ext == ".brep" || ext == ".brp";
    PARAFAB_INPUT_ERROR("part file " << path << " is neither STEP (no ISO-10303-21 header) nor BREP (no "
                                     << "'CASCADE Topology' header)"
                                     << (claims ? " although its extension is " + ext : std::string()));
  }
  if (format == Format::brep) {
    in.clear();
    in.seekg(0);
    return make_part(read_brep_stream(in, path), path, options);
  }
  // OCCT's STEP reader shares global state (Interface_Static, the messenger, the protocol's
  // libraries): two reads at once failed 2 times in 3. One STEP read at a time in a process.
  static std::mutex step_reader_mutex;
  const std::lock_guard<std::mutex> one_reader(step_reader_mutex);
  STEPControl_Reader reader;
  const CaptureStdout log;
  return guarded(path + " (reading STEP)", [&] {
    if (reader.ReadFile(path.c_str()) != IFSelect_RetDone)
      PARAFAB_INPUT_ERROR("part file " << path << " is not a readable STEP file" << log.detail());
    // A file whose entities fail their load checks (a reference to an entity that is not there,
    // a parameter of the wrong type) is refused here: OCCT 7.6's translator dereferences such
    // entities without checking and crashes (found by tests/fuzz/fuzz_inputs.cpp).
    const Interface_CheckIterator checks = reader.WS()->ModelCheckList();
    for (checks.Start(); checks.More(); checks.Next()) {
      const Handle(Interface_Check)& check = checks.Value();
      if (!check->HasFailed()) continue;
      const int n = checks.Number();  // 0: the file as a whole
      const std::string where = n > 0 && n <= reader.Model()->NbEntities()
                                    ? std::string("entity ") + reader.Model()->StringLabel(reader.Model()->Value(n))->ToCString()
                                    : std::string("the file");
      PARAFAB_INPUT_ERROR("part file " << path << " is not a valid STEP file: " << where << ": " << check->CFail(1));
    }
    if (reader.TransferRoots() == 0 || reader.NbShapes() == 0)
      PARAFAB_INPUT_ERROR("part file " << path << ": STEP holds no shape that OpenCASCADE can transfer"
                                       << log.detail());
    const TopoDS_Shape shape = reader.OneShape();
    TopTools_IndexedMapOfShape solids;
    TopExp::MapShapes(shape, TopAbs_SOLID, solids);
    return make_part(shape, path, options, step_solid_names(reader, solids));
  });
}

std::shared_ptr<const PartShape> read_part_from_brep_string(const std::string& brep,
                                                            const ReadOptions& options) {
  const std::string src = "BRep string";
  if (brep.find_first_not_of(" \t\r\n") == std::string::npos) PARAFAB_INPUT_ERROR(src << " is empty");
  if (sniff(brep.substr(0, 4096)) != Format::brep)
    PARAFAB_INPUT_ERROR(
        src << " is not BREP text (no 'CASCADE Topology' header; expected Shape.exportBrepToString())");
  std::istringstream in(brep);
  return make_part(read_brep_stream(in, src), src, options);
}

namespace {

// The tight bounding box (BRepBndLib::AddOptimal, no triangulation, no tolerance enlargement).
void tight_box(const TopoDS_Shape& shape, Eigen::Vector3d& min, Eigen::Vector3d& max) {
  Bnd_Box box;
  BRepBndLib::AddOptimal(shape, box, false, false);
  double x0, y0, z0, x1, y1, z1;
  box.Get(x0, y0, z0, x1, y1, z1);
  min = {x0, y0, z0};
  max = {x1, y1, z1};
}

}  // namespace

PartBoxArea part_box_and_area(const PartShape& part) {
  PartBoxArea size;
  tight_box(part.shape, size.min, size.max);
  GProp_GProps props;
  BRepGProp::SurfaceProperties(part.shape, props);
  size.area = props.Mass();
  GProp_GProps vprops;
  BRepGProp::VolumeProperties(part.shape, vprops);
  size.volume = std::abs(vprops.Mass());
  return size;
}

PartBox part_box(const PartShape& part) {
  PartBox box;
  tight_box(part.shape, box.min, box.max);
  return box;
}

PartInfo part_info(const PartShape& part) {
  PartInfo info;
  info.source = part.source;
  info.name = part.name;
  info.solid_index = part.solid_index;
  info.solid_count = part.solid_count;
  info.face_count = part.face_count();
  info.edge_count = part.edge_count();
  info.vertex_count = part.vertices.Extent();
  tight_box(part.shape, info.bbox_min, info.bbox_max);
  GProp_GProps vprops, sprops;
  BRepGProp::VolumeProperties(part.shape, vprops, 1e-9);  // adaptive: the fixed rule is off by ~1e-5 on B-spline faces
  BRepGProp::SurfaceProperties(part.shape, sprops, 1e-9);
  info.volume = vprops.Mass();
  info.area = sprops.Mass();
  return info;
}

namespace {
std::shared_ptr<const PartShape> transformed_part(const PartShape& part, const gp_Trsf& t, const char* what) {
  auto out = std::make_shared<PartShape>(part);
  out->shape = BRepBuilderAPI_Transform(part.shape, t, /*copy=*/true).Shape();
  out->faces.Clear(), out->edges.Clear(), out->vertices.Clear();
  TopExp::MapShapes(out->shape, TopAbs_FACE, out->faces);
  TopExp::MapShapes(out->shape, TopAbs_EDGE, out->edges);
  TopExp::MapShapes(out->shape, TopAbs_VERTEX, out->vertices);
  PARAFAB_VERIFY(out->faces.Extent() == part.faces.Extent() && out->edges.Extent() == part.edges.Extent(),
                 what << " changed the face or edge count");
  return out;
}
}  // namespace

std::shared_ptr<const PartShape> translated_part(const PartShape& part, const Eigen::Vector3d& offset) {
  gp_Trsf t;
  t.SetTranslation(gp_Vec(offset.x(), offset.y(), offset.z()));
  return transformed_part(part, t, "translation");
}

std::shared_ptr<const PartShape> rotated_part(const PartShape& part, const Eigen::Vector3d& center,
                                              const Eigen::Vector3d& axis, double degrees) {
  PARAFAB_VERIFY(axis.norm() > 0, "rotation axis must not be zero");
  gp_Trsf t;
  t.SetRotation(gp_Ax1(gp_Pnt(center.x(), center.y(), center.z()), gp_Dir(axis.x(), axis.y(), axis.z())),
                degrees * M_PI / 180.0);
  return transformed_part(part, t, "rotation");
}

}  // namespace parafab::occ
