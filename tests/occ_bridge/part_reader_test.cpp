// Tests of the part reader (thesis §6.2.1 input): every sample in samples/parts reads as one
// valid solid; BREP files and strings; solid selection; each invalid input names its problem.
#include "part_reader.h"

#include <gtest/gtest.h>

#include <BRepAlgoAPI_Cut.hxx>
#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_MakeVertex.hxx>
#include <BRepBuilderAPI_MakeWire.hxx>
#include <BRepGProp.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <BRepTools.hxx>
#include <BRep_Builder.hxx>
#include <BRep_Tool.hxx>
#include <GProp_GProps.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Compound.hxx>
#include <TopoDS_Shell.hxx>
#include <TopoDS_Solid.hxx>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <BRepExtrema_DistShapeShape.hxx>
#include <random>

#include "common/error.h"
#include "face_lookup.h"
#include "occt_shape.h"

namespace parafab::occ {
namespace {

std::string sample(const std::string& name) { return std::string(PARAFAB_SAMPLES_DIR) + "/parts/" + name; }

// A file in a per-test temporary folder.
class PartReaderFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("parafab_part_reader_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path) << text;
    return path;
  }
  std::string write_brep(const std::string& name, const TopoDS_Shape& shape) {
    const std::string path = (dir_ / name).string();
    EXPECT_TRUE(BRepTools::Write(shape, path.c_str()));
    return path;
  }
  std::filesystem::path dir_;
};

// Runs f, expects parafab::Error whose message contains every one of `parts`.
template <class F>
void expect_error(F&& f, std::initializer_list<const char*> parts) {
  try {
    f();
    ADD_FAILURE() << "no parafab::Error thrown";
  } catch (const Error& e) {
    for (const char* p : parts) EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what();
  }
}

std::string to_brep_string(const TopoDS_Shape& shape) {
  std::ostringstream os;
  BRepTools::Write(shape, os);
  return os.str();
}

TopoDS_Shape box(double x0 = 0) { return BRepPrimAPI_MakeBox(gp_Pnt(x0, 0, 0), 10, 20, 30).Shape(); }

TEST(PartReader, ReadsEverySampleAsOneValidSolid) {
  const std::vector<std::pair<std::string, int>> faces = {{"box", 6},     {"cylinder", 3}, {"l_bracket", 12},
                                                          {"wrench", 21}, {"ring", 4},     {"half_torus", 3},
                                                          {"wheel", 24},  {"housing", 42}};
  for (const auto& [name, count] : faces) {
    SCOPED_TRACE(name);
    const auto part = read_part(sample(name + ".step"));
    EXPECT_EQ(part->shape.ShapeType(), TopAbs_SOLID);
    EXPECT_EQ(part->face_count(), count);
    const PartInfo info = part_info(*part);
    EXPECT_EQ(info.face_count, count);
    EXPECT_EQ(info.solid_count, 1);
    EXPECT_GT(info.volume, 0);
  }
  const PartInfo b = part_info(*read_part(sample("box.step")));
  EXPECT_NEAR(b.volume, 40 * 30 * 20, 1e-6);
  EXPECT_NEAR(b.area, 2 * (40 * 30 + 40 * 20 + 30 * 20), 1e-6);
  EXPECT_LT((b.bbox_max - Eigen::Vector3d(40, 30, 20)).norm(), 1e-6);
  EXPECT_NEAR(part_info(*read_part(sample("cylinder.step"))).volume, M_PI * 15 * 15 * 40, 1e-6);
  EXPECT_NEAR(part_info(*read_part(sample("ring.step"))).volume, M_PI * (30 * 30 - 20 * 20) * 10, 1e-6);
}

TEST(PartReader, FaceAndEdgeIndicesFollowTopExpMapShapes) {
  const auto part = read_part(sample("l_bracket.step"));
  TopTools_IndexedMapOfShape faces, edges;
  TopExp::MapShapes(part->shape, TopAbs_FACE, faces);
  TopExp::MapShapes(part->shape, TopAbs_EDGE, edges);
  ASSERT_EQ(part->face_count(), faces.Extent());
  ASSERT_EQ(part->edge_count(), edges.Extent());
  for (int i = 0; i < part->face_count(); ++i) {
    EXPECT_TRUE(part->face(i).IsSame(faces(i + 1)));
    EXPECT_EQ(part->face_index(faces(i + 1)), i);
  }
  for (int i = 0; i < part->edge_count(); ++i) EXPECT_EQ(part->edge_index(edges(i + 1)), i);
  // Reading again gives the same numbering (same areas face by face).
  const auto again = read_part(sample("l_bracket.step"));
  for (int i = 0; i < part->face_count(); ++i) {
    GProp_GProps a, b;
    BRepGProp::SurfaceProperties(part->face(i), a);
    BRepGProp::SurfaceProperties(again->face(i), b);
    EXPECT_NEAR(a.Mass(), b.Mass(), 1e-9) << "face " << i;
  }
}

TEST_F(PartReaderFiles, ReadsBrepFilesAndStrings) {
  const auto from_file = read_part(write_brep("box.brep", box()));
  EXPECT_EQ(from_file->face_count(), 6);
  // The format comes from the content: a BREP under another extension reads too.
  EXPECT_EQ(read_part(write_brep("box.dat", box()))->face_count(), 6);
  const auto from_string = read_part_from_brep_string(to_brep_string(box()));
  EXPECT_EQ(from_string->face_count(), 6);
  EXPECT_EQ(from_string->source, "BRep string");
  EXPECT_NEAR(part_info(*from_string).volume, 6000, 1e-9);
}

TEST_F(PartReaderFiles, ChoosesOneOfSeveralSolids) {
  TopoDS_Compound two;
  BRep_Builder b;
  b.MakeCompound(two);
  b.Add(two, box());
  b.Add(two, BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(50, 0, 0), gp::DZ()), 5, 10).Shape());
  const std::string path = write_brep("two.brep", two);
  expect_error([&] { read_part(path); }, {"two.brep", "2 solids", "solid_index"});
  ReadOptions second;
  second.solid_index = 1;
  const auto cyl = read_part(path, second);
  EXPECT_EQ(cyl->face_count(), 3);
  EXPECT_EQ(cyl->solid_index, 1);
  EXPECT_EQ(cyl->solid_count, 2);
  second.solid_index = 2;
  expect_error([&] { read_part(path, second); }, {"solid_index 2 is out of range", "2 solid(s)"});
  second.solid_name = "x";
  expect_error([&] { read_part(path, second); }, {"not both"});
}

TEST(PartReader, ChoosesAStepSolidByName) {
  const std::string path = sample("two_blocks.step");
  expect_error([&] { read_part(path); }, {"2 solids", "'left_block'", "'right_block'"});
  ReadOptions by_name;
  by_name.solid_name = "right_block";
  const auto right = read_part(path, by_name);
  EXPECT_EQ(right->name, "right_block");
  EXPECT_EQ(right->face_count(), 3);  // cylinder r=8
  by_name.solid_name = "left_block";
  EXPECT_EQ(read_part(path, by_name)->face_count(), 6);
  by_name.solid_name = "middle_block";
  expect_error([&] { read_part(path, by_name); }, {"no solid named 'middle_block'", "1 'right_block'"});
}

TEST_F(PartReaderFiles, RejectsMissingEmptyAndForeignFiles) {
  expect_error([&] { read_part((dir_ / "nope.step").string()); }, {"not found", "nope.step"});
  expect_error([&] { read_part(dir_.string()); }, {"is a directory"});
  expect_error([&] { read_part(write("empty.step", "")); }, {"empty.step", "is empty"});
  expect_error([&] { read_part(write("blank.brep", "  \n\n")); }, {"is empty"});
  expect_error([&] { read_part(write("notes.txt", "hello world\n")); },
               {"notes.txt", "neither STEP", "nor BREP"});
  expect_error([&] { read_part(write("fake.step", "solid cube\nfacet normal 0 0 1\n")); },
               {"fake.step", "neither STEP", "although its extension is .step"});
  expect_error([&] { read_part(write("broken.step", "ISO-10303-21;\nHEADER;\nthis is not step\n")); },
               {"broken.step"});
  expect_error(
      [&] { read_part(write("broken.brep", "DBRep_DrawableShape\n\nCASCADE Topology V1\nLocations 3\n")); },
      {"broken.brep"});
  expect_error([&] { read_part_from_brep_string(""); }, {"BRep string is empty"});
  expect_error([&] { read_part_from_brep_string("ISO-10303-21;"); }, {"not BREP text"});
}

TEST_F(PartReaderFiles, RejectsAShapeWithoutSolid) {
  TopExp_Explorer face(box(), TopAbs_FACE);
  expect_error([&] { read_part(write_brep("face.brep", face.Current())); },
               {"face.brep", "no solid", "open shell", "4 edge(s) bound only one face"});
  TopExp_Explorer shell(box(), TopAbs_SHELL);
  expect_error([&] { read_part_from_brep_string(to_brep_string(shell.Current())); },
               {"no solid", "closed shell of 6 faces"});
  expect_error(
      [&] {
        read_part_from_brep_string(
            to_brep_string(BRepBuilderAPI_MakeEdge(gp_Pnt(0, 0, 0), gp_Pnt(1, 0, 0)).Shape()));
      },
      {"no solid", "no faces"});
}

// A solid with one shell made of `faces`.
TopoDS_Solid solid_of(const std::vector<TopoDS_Shape>& faces) {
  BRep_Builder b;
  TopoDS_Shell shell;
  b.MakeShell(shell);
  for (const auto& f : faces) b.Add(shell, f);
  TopoDS_Solid solid;
  b.MakeSolid(solid);
  b.Add(solid, shell);
  return solid;
}

std::vector<TopoDS_Shape> box_faces() {
  std::vector<TopoDS_Shape> faces;
  for (TopExp_Explorer f(box(), TopAbs_FACE); f.More(); f.Next()) faces.push_back(f.Current());
  return faces;
}

TEST(PartReader, RejectsOpenNonManifoldAndInvalidSolids) {
  std::vector<TopoDS_Shape> faces = box_faces();
  faces.pop_back();
  expect_error([&] { make_part(solid_of(faces), "open.brep"); },
               {"open.brep", "open shell (not closed)", "4 edge(s) bound only one face", "first edge"});

  // A fin on one box edge: three faces share that edge.
  faces = box_faces();
  TopExp_Explorer ex(faces[0], TopAbs_EDGE);
  const TopoDS_Edge edge = TopoDS::Edge(ex.Current());
  TopoDS_Vertex v0, v1;
  TopExp::Vertices(edge, v0, v1);
  const gp_Pnt p0 = BRep_Tool::Pnt(v0), p1 = BRep_Tool::Pnt(v1);
  const gp_Vec out = gp_Vec(-1, -1, 0) * 5;  // away from the box at its x = 0 face
  const TopoDS_Vertex w0 = BRepBuilderAPI_MakeVertex(p0.Translated(out)),
                      w1 = BRepBuilderAPI_MakeVertex(p1.Translated(out));
  BRepBuilderAPI_MakeWire wire(edge, BRepBuilderAPI_MakeEdge(v1, w1), BRepBuilderAPI_MakeEdge(w1, w0),
                               BRepBuilderAPI_MakeEdge(w0, v0));
  faces.push_back(BRepBuilderAPI_MakeFace(wire.Wire(), true).Face());
  expect_error([&] { make_part(solid_of(faces), "fin.step"); },
               {"fin.step", "non-manifold solid: edge", "shared by 3 faces"});

  // Closed and manifold, but one face turned inside out.
  faces = box_faces();
  faces[2].Reverse();
  expect_error([&] { make_part(solid_of(faces), "flipped.brep"); },
               {"flipped.brep", "invalid shape", "BRepCheck"});
}

// A part far from the origin (issue 56). translated_part copies the geometry: the box moves by
// the offset exactly. A box with a hole cut at 1e8 mm is valid in memory but fails BRepCheck
// after a BREP write and read (FreeCAD's isValid() says the same): OCCT's tolerances (1e-7) are
// a few ulps of 1e8 (1.5e-8). The refusal names the distance; near the origin it does not.
TEST(PartReader, FarFromTheOrigin) {
  const auto part = read_part(sample("l_bracket.step"));
  const PartBox b0 = part_box(*part);
  const Eigen::Vector3d d(1e7, -3e5, 2048);
  const auto moved = translated_part(*part, d);
  EXPECT_EQ(moved->face_count(), part->face_count());
  EXPECT_EQ(moved->edge_count(), part->edge_count());
  const PartBox b1 = part_box(*moved);
  EXPECT_NEAR((b1.min - b0.min - d).norm(), 0, 1e-8);
  EXPECT_NEAR((b1.max - b0.max - d).norm(), 0, 1e-8);
  EXPECT_EQ(check_failure_description(*moved), "");

  const double far = 1e8;
  const TopoDS_Shape block = BRepPrimAPI_MakeBox(gp_Pnt(far - 5, far - 5, far), 10, 10, 10).Shape();
  const TopoDS_Shape pin =
      BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(far + 0.123456789, far + 0.3, far + 1 / 3.0), gp_Dir(0, 0, 1)), 3, 10)
          .Shape();
  const TopoDS_Shape holed = BRepAlgoAPI_Cut(block, pin).Shape();
  expect_error([&] { read_part_from_brep_string(to_brep_string(holed)); },
               {"invalid shape: BRepCheck reports", "from the origin", "doubles resolve", "move the part nearer"});
  std::vector<TopoDS_Shape> faces = box_faces();
  faces[2].Reverse();
  try {
    make_part(solid_of(faces), "flipped.brep");
    ADD_FAILURE() << "no parafab::Error thrown";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).find("from the origin"), std::string::npos) << e.what();
  }
}

// FaceLocator (faces named by points in a job) against the scan it replaced: the exact distance
// (BRepExtrema) to every face, the nearest one, of equal ones the lowest index. Points: every
// vertex of the part (where several faces are at distance 0: the tie rule), a point near each
// face (its centroid: on a plane face, often off a curved one) and random points in and around
// the box. The bridge's 646 faces are where the pruning matters (its 800 named faces took
// 5.5 minutes to find with the scan).
TEST(PartReader, FaceLocatorFindsTheFacesTheFullScanFinds) {
  for (const std::string name : {"l_bracket", "wrench", "wheel", "housing", "bump_block", "bridge_holes"}) {
    SCOPED_TRACE(name);
    const auto part = read_part(sample(name + ".step"));
    std::vector<Eigen::Vector3d> points;
    for (int i = 1; i <= part->vertices.Extent(); ++i) {
      const gp_Pnt v = BRep_Tool::Pnt(TopoDS::Vertex(part->vertices(i)));
      points.emplace_back(v.X(), v.Y(), v.Z());
    }
    for (int f = 0; f < part->face_count(); ++f) {
      GProp_GProps g;
      BRepGProp::SurfaceProperties(part->face(f), g);
      points.emplace_back(g.CentreOfMass().X(), g.CentreOfMass().Y(), g.CentreOfMass().Z());
    }
    const PartInfo info = part_info(*part);
    std::mt19937 rng(7);
    for (int k = 0; k < 40; ++k) {
      Eigen::Vector3d X;
      for (int a = 0; a < 3; ++a)
        X[a] = std::uniform_real_distribution<double>(info.bbox_min[a] - 5, info.bbox_max[a] + 5)(rng);
      points.push_back(X);
    }
    if (part->face_count() > 100) {  // the scan is slow: 120 points spread over the three kinds
      std::vector<Eigen::Vector3d> some;
      for (size_t k = 0; k < points.size(); k += points.size() / 120) some.push_back(points[k]);
      for (size_t k = points.size() - 20; k < points.size(); ++k) some.push_back(points[k]);  // random ones
      points = some;
    }
    const FaceLocator locator(*part);
    for (const Eigen::Vector3d& X : points) {
      const TopoDS_Vertex v = BRepBuilderAPI_MakeVertex(gp_Pnt(X.x(), X.y(), X.z()));
      int best = -1;
      double best_d = 1e300;
      for (int i = 0; i < part->face_count(); ++i) {
        BRepExtrema_DistShapeShape dist(v, part->face(i));
        if (dist.IsDone() && dist.Value() < best_d) best_d = dist.Value(), best = i;
      }
      const int found = locator.face_at(X, 1e300);
      ASSERT_EQ(found, best) << "(" << X.transpose() << "), nearest at " << best_d;
      EXPECT_EQ(face_at_point(*part, X, 1e300), best);
    }
    // No face within the tolerance: the error names the point and the nearest face.
    const Eigen::Vector3d far = info.bbox_max + Eigen::Vector3d(50, 0, 0);
    try {
      locator.face_at(far, 1e-3);
      ADD_FAILURE() << "a point 50 mm off the part found a face";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("no face of"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("the nearest is face"), std::string::npos) << e.what();
    }
    std::printf("%s: the locator and the scan agree on %zu points (%d faces)\n", name.c_str(), points.size(),
                part->face_count());
  }
}

}  // namespace
}  // namespace parafab::occ
