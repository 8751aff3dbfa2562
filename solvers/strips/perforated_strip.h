// Perforated strips (thesis §4.7.1, Fig. 4.13 left): a strip of prescribed outer width w(s)
// whose diamond-shaped holes leave, across every section, the solid width w_K(s) that the
// stiffness needs (K ∝ w_K for a sheet of constant thickness).
//
// Layout: m columns; rows of diamonds every p/2 along s, alternating m diamonds centred in
// the m lateral cells (type A) and m − 1 diamonds on the cell boundaries (type B). Every
// diamond spans p along s. A section at relative distance τ = 2|t|/p from an A row cuts
// m D_A (1 − τ) + (m − 1) D_B τ of holes, so D_A = H/m and D_B = H/(m − 1) with
// H = w − w_K remove exactly H everywhere (up to the variation of H over one row).
// The strands between holes run at atan(c/p) to the strip axis (c = w/m).
#pragma once

#include <array>
#include <string>
#include <vector>

#include "common/bspline.h"

namespace parafab {

struct PerforatedStripOptions {
  double min_ligament = 1.5e-3;  ///< narrowest strand of material between holes / to the edge [m]
  int columns = 0;               ///< m ≥ 2; 0: the smallest feasible m (largest holes)
  double cell_aspect = 4.0;      ///< p / (mean w / m): diamond length over lateral cell width
  int max_columns = 64;
};

struct Diamond {
  double s = 0;        ///< centre, arc length [m]
  double offset = 0;   ///< centre, across the strip (centreline at 0) [m]
  double length = 0;   ///< along s [m]
  double width = 0;    ///< across [m]
  /// Corners counter-clockwise in flat strip coordinates (s, offset): −s tip first.
  std::array<Vec2, 4> corners() const;
};

struct PerforatedStripResult {
  bool feasible = false;
  int columns = 0;
  double pitch = 0;                ///< p [m]
  std::vector<Diamond> diamonds;
  double perforated_from = 0, perforated_to = 0;  ///< s range covered by full rows
  double worst_s = -1;             ///< where feasibility fails
  std::string message;
  // Deviation of the realized pattern from the designed profile (feasible results; sections
  // every pitch/64 over the whole strip). The section's material width w_mat(s) is linear
  // between rows, so it misses a curved w_K by O(p²·w_K''); the end zones before the first
  // and after the last row have no holes (stiffer than designed).
  double max_width_deviation = 0;      ///< max |w_mat/w_K − 1| over every section
  double max_width_deviation_s = -1;   ///< where
  /// Homogenized bending stiffness over one pitch (sections in series: p / ∫ds/w), realized
  /// against designed: max |K_eff/K_design − 1| over windows of one pitch inside the strip.
  double max_stiffness_deviation = 0;
  double max_stiffness_deviation_s = -1;  ///< centre of that window
  double end_zone_deviation = 0;       ///< max w/w_K − 1 where no hole cuts the section
  /// The same two figures inside the perforated range [perforated_from, perforated_to] only
  /// (sections there; windows of one pitch lying within it): the pattern's own error, without
  /// the hole-free end zones that dominate the maxima above.
  double interior_width_deviation = 0;
  double interior_width_deviation_s = -1;
  double interior_stiffness_deviation = 0;
  double interior_stiffness_deviation_s = -1;
};

/// `s` sorted, `outer_width` w(s) and `solid_width` w_K(s) ≤ w(s) (e.g. StripDesign::width),
/// equal lengths ≥ 2. Throws parafab::Error naming the offending input; a width that cannot
/// be reached (w_K > w, or strands thinner than min_ligament) is feasible = false.
PerforatedStripResult design_perforated_strip(const std::vector<double>& s,
                                              const std::vector<double>& outer_width,
                                              const std::vector<double>& solid_width,
                                              const PerforatedStripOptions& options = {});

/// Material width across the strip at arc length `at`: w(at) minus the holes the section cuts.
double perforated_material_width(const PerforatedStripResult& strip, const std::vector<double>& s,
                                 const std::vector<double>& outer_width, double at);

}  // namespace parafab
