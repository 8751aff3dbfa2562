"""FreeCAD "Optimize shape": shape optimization of a solid on its own CAD parameters (thesis §6.5).

Non-GUI core of the "Optimize shape" command (the task panel is :mod:`parafab_wb.optimize_panel`):

* :func:`face_model` -- the faces of a solid, their parameter names and the relation groups
  (faces linked by the face model's tangency or coaxial relations: moving one drags the others
  along).
* :func:`build_job` -- the ``parafab optimize`` job (resources/doc/optimization.md, "The job") from panel
  options that name faces the FreeCAD way (``FaceN`` = ParaFab face N − 1).
* :func:`optimize_shape` -- export the solid, run ``parafab.optimize`` in-process and add the
  optimized solid as a NEW ``Part::Feature`` beside the original (:func:`add_result`).

Bounds: volume ratios (``max_volume_ratio`` / ``min_volume_ratio``, the job's ``max_ratio`` /
``min_ratio``) and masses in kg (``max_mass`` / ``min_mass``,
:func:`mass_constraint`: density [kg/m³] × 1e-9 × volume [mm³]); a run with a mass bound gives
its result ``InitialMass`` / ``FinalMass`` (history.json's ``initial_mass`` / ``final_mass``).

The "target" objective (rest-shape design) matches one face (option ``target_face``, ``FaceN``)
under the load onto its own CAD surface (plane, cylinder, sphere or torus; the engine's default:
no ``"target"`` is sent), with the supports, loads and material of "compliance"; its result gets
``TargetFace`` and ``InitialTargetRms`` / ``FinalTargetRms`` [mm] (:func:`target_summary`).

The original is never changed. Every error (not a solid, bad face, engine error, invalid
result, cancel) raises :class:`OptimizeError` before anything is added to the document.
The shape is optimized in the object's local coordinates (exported as BREP, which keeps the
face order); the axis of the objective is given in global coordinates and transformed; the
new object gets the original's placement.
"""

import json
import math
import os
import re
import shutil
import tempfile

import FreeCAD

CANCELLED = "cancelled"
#: The history status of a run stopped by Cancel, a signal or the progress callback.
INTERRUPTED = "interrupted"
RESULT_SUFFIX = "_optimized"


class OptimizeError(RuntimeError):
    """Bad input, an engine error or a cancelled run: the document is left unchanged."""


class Objective(object):
    """One objective type of the engine, as offered by the panel.

    ``uses`` names the inputs the job must carry for it: "axis" (objective.axis), "density"
    (objective.density), "material", "supports", "loads" (simulation-job format), "failure"
    (objective.yield_stress, exponent, normalize), "target" (objective.face: the matched face,
    option ``target_face``; objective.target only when the option ``target_surface`` is given).
    Supports and loads are always sent when given. The engine keeps their faces fixed unless a
    picked parameter is on one (then the support or load moves with its face).
    """

    def __init__(self, type, label, tooltip, uses=(), terms=()):
        self.type = type
        self.label = label
        self.tooltip = tooltip
        self.uses = tuple(uses)
        #: For a weighted sum: the engine types of its terms (the job gets {"type": "sum",
        #: "normalize": true, "terms": [...]}, weights from the option "weights", default 1 each).
        self.terms = tuple(terms)


#: Objective types offered by the panel, in order. Extend with :func:`register_objective`.
OBJECTIVES = [
    Objective("center_of_mass", "Centre of mass onto the axis",
              "|c⊥|²: squared distance of the centre of mass from the axis (static balance)", ("axis",)),
    Objective("inertia_alignment", "Axis a principal axis of inertia",
              "|I a − (aᵀIa) a|² / (tr I)²: the axis a principal axis of inertia about the centre",
              ("axis",)),
    Objective("balance", "Balance (centre + principal axis)",
              "centre-of-mass term / L² + inertia alignment (static and dynamic balance)", ("axis",)),
    Objective("mass", "Mass", "ρV (density in kg/m³)", ("density",)),
    Objective("volume", "Volume", "V"),
    Objective("compliance", "Compliance (stiffness)",
              "fᵀu of the linear XFEM solve on a fixed grid (exact gradient by the rule derivatives): lower is stiffer; "
              "combine with a volume bound", ("material", "supports", "loads")),
    Objective("failure", "Failure (von Mises stress)",
              "(1/V)∫exp(α(σ_vm/σ_y − 1))dV of the linear XFEM solve (thesis Eq. 6.4, adjoint gradient): a smooth "
              "maximum of the von Mises stress relative to the yield stress", ("material", "supports", "loads", "failure")),
    Objective("balance_and_compliance", "Balance + compliance (normalized sum)",
              "balance / its start value + compliance / its start value (weights: option 'weights'), "
              "e.g. a wheel balanced about its axis that must stay stiff",
              ("axis", "material", "supports", "loads"), terms=("balance", "compliance")),
    Objective("compliance_and_failure", "Stiffness + stress (normalized sum)",
              "compliance / its start value + failure metric / its start value (weights: option 'weights'): "
              "stiffer and with a lower peak von Mises stress", ("material", "supports", "loads", "failure"),
              terms=("compliance", "failure")),
    Objective("target", "Target shape (face under load onto its CAD surface)",
              "(1/A)∫d(X + u)²dA of the linear XFEM solve (thesis Eq. 6.6, adjoint gradient): the mean squared "
              "distance [mm²] of the matched face's deformed points from its own surface as modelled (plane, "
              "cylinder, sphere or torus): the rest shape is designed so that the loaded face lands where the CAD "
              "model puts it. Pick the matched face (not a support); the result reports its RMS distance in mm",
              ("material", "supports", "loads", "target")),
]


def register_objective(objective):
    """Add (or replace, by type) an objective offered by the panel."""
    for i, o in enumerate(OBJECTIVES):
        if o.type == objective.type:
            OBJECTIVES[i] = objective
            return
    OBJECTIVES.append(objective)


def objective_by_type(type):
    for o in OBJECTIVES:
        if o.type == type:
            return o
    raise OptimizeError("unknown objective type '%s' (available: %s)" % (type, ", ".join(o.type for o in OBJECTIVES)))


#: FreeCAD surface types whose own surface can be a target (the engine's closed-form distances).
TARGET_SURFACES = {"Part::GeomPlane": "plane", "Part::GeomCylinder": "cylinder", "Part::GeomSphere": "sphere",
                   "Part::GeomToroid": "torus"}


#: Parameter names per face type (the engine's block names, solvers/optimize/shape_constraints.cpp).
PARAMETER_NAMES = {
    "plane": ("offset", "normal x", "normal y", "normal z"),
    "cylinder": ("radius", "axis point x", "axis point y", "axis point z", "axis x", "axis y", "axis z"),
    "cone": ("radius", "half-angle", "axis point x", "axis point y", "axis point z", "axis x", "axis y", "axis z"),
    "sphere": ("radius", "centre x", "centre y", "centre z"),
    "torus": ("minor radius", "major radius", "centre x", "centre y", "centre z", "axis x", "axis y", "axis z"),
}


def parameter_names(face):
    """Parameter names of one face of ``parafab.inspect_part``: the block names of an analytic
    face, ``pole i j x|y|z`` (1-based, as ``BSplineSurface.getPole``) of a non-periodic B-spline
    face, none otherwise."""
    if "pole_count" in face:
        nu, nv = face["pole_count"]
        return ["pole %d %d %s" % (i, j, c) for i in range(1, nu + 1) for j in range(1, nv + 1) for c in "xyz"]
    return list(PARAMETER_NAMES.get(face["type"], ()))


def default_parameter(face_type):
    """The parameter a picked face contributes by default (offset or radius), or None."""
    names = PARAMETER_NAMES.get(face_type)
    return names[0] if names else None


def solid_shape(obj):
    """The shape of ``obj`` when it is one valid solid; raises :class:`OptimizeError` otherwise."""
    if obj is None:
        raise OptimizeError("no object selected: select one solid")
    shape = getattr(obj, "Shape", None)
    label = getattr(obj, "Label", "?")
    if shape is None or shape.isNull():
        raise OptimizeError("%s has no shape: select a solid" % label)
    if len(shape.Solids) != 1:
        raise OptimizeError("%s is not a single solid (%d solids, %d faces): select one solid"
                            % (label, len(shape.Solids), len(shape.Faces)))
    if not shape.isValid():
        raise OptimizeError("%s is not a valid solid (Part > Check geometry names the problem)" % label)
    return shape


def _local_shape(obj):
    """``(shape without placement, placement)`` of ``obj``'s solid."""
    shape = solid_shape(obj).copy()
    placement = shape.Placement
    shape.Placement = FreeCAD.Placement()
    return shape, placement


def face_index(name, n_faces, what):
    """ParaFab face index of a FreeCAD face name ``FaceN`` (or an int index, passed through)."""
    if isinstance(name, int):
        index = name
    elif isinstance(name, str) and name.startswith("Face") and name[4:].isdigit():
        index = int(name[4:]) - 1
    else:
        raise OptimizeError("%s: '%s' is not a face name (Face1..Face%d)" % (what, name, n_faces))
    if not 0 <= index < n_faces:
        raise OptimizeError("%s: Face%d is not a face of the part (Face1..Face%d)" % (what, index + 1, n_faces))
    return index


def face_model(obj):
    """Faces and relation groups of ``obj``'s solid, from ``parafab.inspect_part``.

    Returns ``{"faces": [{"name": "FaceN", "index", "type", "parameters": [names]}],
    "groups": [[FaceN, ...]]}``: a group is a set of faces connected by the face model's
    relations, tangencies and coaxial faces of revolution (two or more faces; faces in no
    relation are in no group)."""
    import parafab
    shape, _ = _local_shape(obj)
    tmp = tempfile.mkdtemp(prefix="parafab_inspect_")
    try:
        brep = os.path.join(tmp, "part.brep")
        shape.exportBrep(brep)
        model = parafab.inspect_part(brep)
    except Exception as exc:
        raise OptimizeError("cannot read the face model of %s: %s" % (obj.Label, exc))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    faces = [{"name": "Face%d" % (f["index"] + 1), "index": f["index"], "type": f["type"],
              "parameters": parameter_names(f)} for f in model["faces"]]
    parent = list(range(len(faces)))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    for rel in model.get("relations", []):
        a, b = rel["faces"][0], rel["faces"][1]
        parent[find(a)] = find(b)
    groups = {}
    for i in range(len(faces)):
        groups.setdefault(find(i), []).append(i)
    tangent = sorted((g for g in groups.values() if len(g) > 1), key=lambda g: g[0])
    return {"faces": faces, "groups": [["Face%d" % (i + 1) for i in g] for g in tangent],
            "relations": len(model.get("relations", []))}


def default_options():
    """Panel options with their defaults (see :func:`build_job`)."""
    return {
        "objective": "center_of_mass",
        "axis_point": (0.0, 0.0, 0.0),       # global coordinates [mm]
        "axis_direction": (0.0, 0.0, 1.0),
        "density": 7850.0,                    # kg/m³
        "parameters": "auto",                 # or [("FaceN", "radius"), ("FaceM", "radius", min, max), ...]
        #   min/max: absolute bounds (None: none); offsets and axis points in the part's own frame
        "ties": [],                           # [[("FaceN", "radius"), ("FaceM", "radius")], ...]
        "fixed_faces": [],                    # ["FaceN", ...]
        "draft_faces": [],                    # ["FaceN", ...]: planes (normal ⊥ pull), cylinders/cones (axis ∥ pull)
        "draft_direction": (0.0, 0.0, 1.0),   # pull direction (global), for draft_faces
        "pattern_faces": [],                  # ["FaceN", ...]: equal faces turned about the pattern axis
        "pattern_axis_point": (0.0, 0.0, 0.0),      # global [mm]
        "pattern_axis_direction": (0.0, 0.0, 1.0),  # global
        "mirror_faces": [],                   # ["FaceN", ...]: faces paired by their image in the mirror plane
        "mirror_plane_point": (0.0, 0.0, 0.0),      # global [mm]
        "mirror_plane_normal": (1.0, 0.0, 0.0),     # global
        "supports": [],                       # ["FaceN", ...]
        "loads": [],                          # ["FaceN", ...]
        "force": (0.0, 0.0, 0.0),             # total force on the loaded faces [N]
        "E": 210000.0, "nu": 0.3,             # MPa, for objectives that use "material"
        "yield_stress": 250.0,                # MPa, objective "failure"
        "exponent": 8.0,                      # α of objective "failure" (larger: nearer the maximum)
        "normalize": True,                    # "failure": divide the integral by the volume
        "target_face": None,                  # "FaceN": the face matched by objective "target" (not a support)
        "target_surface": None,               # "target": None (the face's own surface) or the engine's
        #   {"plane" | "cylinder" | "sphere" | "torus": {...}} in the part's own frame, sent as given
        "max_iterations": 20,
        "max_volume_ratio": None,             # e.g. 1.05: volume at most 105 % of the start
        "min_volume_ratio": None,             # e.g. 0.9: volume at least 90 % of the start
        "max_mass": None,                     # kg (density × volume, see mass_constraint); None or 0: no bound
        "min_mass": None,                     # kg; None or 0: no bound
        "cells": None,                        # grid cells along the longest side (compliance; None: engine default)
        "nitsche_penalty": "fixed",           # clamp on cut cells: "fixed" (100 E/h) or "local" (per cell)
        "merge_penalty": False,               # compliance alone: tie pieces about to join (thesis Eq. 6.24)
        "bound": 0.3,
        "relative_improvement": 1e-9,
    }


def _picked_faces(opts, key, need_two):
    names = list(opts[key])
    if len(names) < 2:
        raise OptimizeError("%s, got %d" % (need_two, len(names)))
    return names


def _local_point_and_direction(opts, point_key, direction_key, default_direction, placement, what):
    """A point and a unit direction given globally in ``opts``, in the part's frame; raises
    :class:`OptimizeError` "<what> is zero" for a zero direction."""
    inv = (placement or FreeCAD.Placement()).inverse()
    direction = FreeCAD.Vector(*opts.get(direction_key, default_direction))
    if direction.Length < 1e-12:
        raise OptimizeError("%s is zero" % what)
    d = inv.Rotation.multVec(direction)
    d.normalize()
    return inv.multVec(FreeCAD.Vector(*opts.get(point_key, (0.0, 0.0, 0.0)))), d


def pattern_rotation(shape, opts, placement=None):
    """The job's "rotations" entry for the picked pattern faces: sorted by their angle about the
    pattern axis (centres of mass, in the part's frame), the step angle from consecutive
    centres, which must be equally spaced (to 1e-6 rad). Raises :class:`OptimizeError` naming
    the faces that do not fit."""
    names = _picked_faces(opts, "pattern_faces", "a pattern needs at least two faces")
    n = len(shape.Faces)
    o, w = _local_point_and_direction(opts, "pattern_axis_point", "pattern_axis_direction", (0.0, 0.0, 1.0),
                                      placement, "the pattern axis direction")
    size = shape.BoundBox.DiagonalLength
    placed = []
    for name in names:
        i = face_index(name, n, "pattern faces")
        r = shape.Faces[i].CenterOfMass - o
        r = r - w * r.dot(w)
        if r.Length < 1e-9 * size:
            raise OptimizeError("pattern face %s lies on the pattern axis (nothing to turn)" % name)
        placed.append((i, name, r))
    e1 = FreeCAD.Vector(placed[0][2])
    e1.normalize()
    e2 = w.cross(e1)
    placed.sort(key=lambda f: math.atan2(f[2].dot(e2), f[2].dot(e1)) % (2 * math.pi))
    angles = [math.atan2(f[2].dot(e2), f[2].dot(e1)) % (2 * math.pi) for f in placed]
    steps = [b - a for a, b in zip(angles, angles[1:])]
    if max(steps) - min(steps) > 1e-6:
        raise OptimizeError("pattern faces are not equally spaced about the axis: %s at %s°"
                            % (", ".join(f[1] for f in placed), ", ".join("%.4g" % math.degrees(a) for a in angles)))
    return {"faces": [f[0] for f in placed], "axis": {"point": [o.x, o.y, o.z], "direction": [w.x, w.y, w.z]},
            "degrees": math.degrees(sum(steps) / len(steps))}


def mirror_pairs(shape, opts, placement=None):
    """The job's "mirrors" entries for the picked mirror faces: each face is paired with the
    picked face whose centre of mass is its image in the mirror plane (to 1e-6 of the part's
    size; plane given globally, written in the part's frame). Raises :class:`OptimizeError`
    naming a face without a partner or one lying on the plane."""
    names = _picked_faces(opts, "mirror_faces", "a mirror needs at least two faces (pairs of images)")
    n = len(shape.Faces)
    point, nl = _local_point_and_direction(opts, "mirror_plane_point", "mirror_plane_normal", (1.0, 0.0, 0.0),
                                           placement, "the mirror plane normal")
    offset = nl.dot(point)
    tol = 1e-6 * shape.BoundBox.DiagonalLength
    centres = []
    for name in names:
        i = face_index(name, n, "mirror faces")
        c = shape.Faces[i].CenterOfMass
        if abs(nl.dot(c) - offset) < tol:
            raise OptimizeError("mirror face %s lies on the mirror plane (it is its own image): "
                                "pick pairs of faces on either side" % name)
        centres.append((i, name, c))
    pairs, used = [], set()
    for k, (i, name, c) in enumerate(centres):
        if k in used:
            continue
        image = c - nl * (2 * (nl.dot(c) - offset))
        match = [m for m, (_, _, d) in enumerate(centres) if m != k and m not in used and (d - image).Length < tol]
        if not match:
            raise OptimizeError("mirror face %s has no picked partner at its image (%.4g, %.4g, %.4g) in the plane"
                                % (name, image.x, image.y, image.z))
        used.update((k, match[0]))
        pairs.append({"faces": [i, centres[match[0]][0]],
                      "plane": {"normal": [nl.x, nl.y, nl.z], "offset": offset}})
    return pairs


#: kg/m³ (the panel's density) → kg/mm³: a mass bound's job entry carries the density in kg/mm³,
#: so that with the part's volume in mm³ the engine's masses (the bounds, history.json's
#: ``initial_mass`` / ``final_mass``) are in kg. (``material.density`` is in t/mm³ for the solver:
#: the entry's own density takes precedence for the bound.)
MASS_DENSITY_SCALE = 1e-9


def mass_constraint(options):
    """The job's ``{"type": "mass", "density", "max", "min"}`` entry for the options'
    ``max_mass`` / ``min_mass`` [kg] (None or 0: no bound; only the bounds set are sent), or None
    when neither is set. Its density is the options' ``density`` [kg/m³] × 1e-9 (kg/mm³), so the
    masses are density × FreeCAD's ``Shape.Volume`` [mm³] in kg. Raises :class:`OptimizeError`
    for a bound that is not a positive number, a min above the max (equal bounds keep the
    mass) or a bound without a positive density."""
    opts = default_options()
    opts.update(options or {})
    entry = {"type": "mass"}
    for key in ("max", "min"):
        value = opts.get(key + "_mass")
        if value is None or value == "" or value == 0:
            continue
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise OptimizeError("mass bound: %s must be a number of kg, got %r" % (key, value))
        if not (math.isfinite(value) and value > 0):
            raise OptimizeError("mass bound: %s must be a positive mass in kg (0: none), got %r" % (key, value))
        entry[key] = value
    if len(entry) == 1:
        return None
    if "min" in entry and "max" in entry and not entry["min"] <= entry["max"]:  # equal: keep the mass
        raise OptimizeError("mass bound: min %g kg must not exceed max %g kg" % (entry["min"], entry["max"]))
    try:
        density = float(opts.get("density") or 0.0)
    except (TypeError, ValueError):
        density = float("nan")
    if not (math.isfinite(density) and density > 0):
        raise OptimizeError("a mass bound needs a positive density (kg/m³), got %r" % (opts.get("density"),))
    entry["density"] = density * MASS_DENSITY_SCALE
    return entry


def start_mass(shape, density):
    """Mass [kg] of ``shape`` at ``density`` [kg/m³]: density × 1e-9 × ``shape.Volume`` [mm³],
    the figure a mass bound of :func:`mass_constraint` is compared with at the start."""
    return float(density) * MASS_DENSITY_SCALE * shape.Volume


def target_entry(shape, opts):
    """``{"face": k}`` (ParaFab index of the option ``target_face``, ``FaceN`` = k + 1), with
    ``"target"`` only when ``target_surface`` is given (else the engine uses the face's own surface).
    Raises :class:`OptimizeError` when no face is chosen, for a face that is a support (it does
    not move) and, without ``target_surface``, for a face that is no plane, cylinder, sphere or
    torus."""
    n = len(shape.Faces)
    name = opts.get("target_face")
    if name is None or name == "":
        raise OptimizeError("objective 'target': no matched face chosen: pick the face that must land on its "
                            "CAD surface under the load")
    index = face_index(name, n, "target face")
    label = "Face%d" % (index + 1)
    if index in [face_index(f, n, "supports") for f in opts.get("supports") or []]:
        raise OptimizeError("target face %s is a support: a clamped face does not move under the load; "
                            "match another face" % label)
    entry = {"face": index}
    given = opts.get("target_surface")
    if given:
        if not isinstance(given, dict):
            raise OptimizeError("target surface: expected {\"plane\" | \"cylinder\" | \"sphere\" | \"torus\": "
                                "{...}}, got %r" % (given,))
        entry["target"] = given
    else:
        kind = shape.Faces[index].Surface.TypeId
        if kind not in TARGET_SURFACES:
            raise OptimizeError("target face %s is a %s: its own surface is a target only for a plane, cylinder, "
                                "sphere or torus" % (label, kind.replace("Part::Geom", "").lower()))
    return entry


def build_job(shape, options, placement=None):
    """The ``parafab optimize`` job for ``options`` (see :func:`default_options`) on the local
    ``shape``; ``placement`` maps local to global coordinates (the axis is given globally)."""
    opts = default_options()
    opts.update(options or {})
    n = len(shape.Faces)
    objective = objective_by_type(opts["objective"])
    obj_json = {"type": objective.type}
    if "axis" in objective.uses:
        inv = (placement or FreeCAD.Placement()).inverse()
        direction = FreeCAD.Vector(*opts["axis_direction"])
        if direction.Length < 1e-12:
            raise OptimizeError("the objective's axis direction is zero")
        point = inv.multVec(FreeCAD.Vector(*opts["axis_point"]))
        d = inv.Rotation.multVec(direction)
        obj_json["axis"] = {"point": [point.x, point.y, point.z], "direction": [d.x, d.y, d.z]}
    if "density" in objective.uses:
        obj_json["density"] = float(opts["density"])
    if "failure" in objective.uses:
        for key in ("yield_stress", "exponent"):
            value = opts.get(key)
            if value is None or not float(value) > 0:
                raise OptimizeError("objective '%s': %s must be positive, got %r" % (objective.type, key, value))
            obj_json[key] = float(value)
        obj_json["normalize"] = bool(opts["normalize"])
    if "target" in objective.uses:
        obj_json.update(target_entry(shape, opts))
    if objective.terms:
        weights = opts.get("weights") or [1.0] * len(objective.terms)
        if len(weights) != len(objective.terms):
            raise OptimizeError("objective '%s' has %d terms but %d weights were given"
                                % (objective.type, len(objective.terms), len(weights)))
        shared = {k: v for k, v in obj_json.items() if k != "type"}
        obj_json = {"type": "sum", "normalize": True,
                    "terms": [dict(shared, type=t, weight=float(w)) for t, w in zip(objective.terms, weights)]}
    job = {"objective": obj_json, "max_iterations": int(opts["max_iterations"]),
           "bound": float(opts["bound"]), "relative_improvement": float(opts["relative_improvement"])}

    def ref(item, what):
        face, name = item[0], item[1]
        return {"face": face_index(face, n, what), "parameter": str(name)}

    def design(item, what):
        # (face, name) or (face, name, min, max): absolute bounds (None: none), in the part's own
        # frame for offsets and axis points (radii and angles do not depend on the frame).
        if len(item) not in (2, 4):
            raise OptimizeError("%s: expected (face, parameter) or (face, parameter, min, max), got %r" % (what, item))
        entry = ref(item, what)
        for key, value in zip(("min", "max"), item[2:]):
            if value is None:
                continue
            try:
                entry[key] = float(value)
            except (TypeError, ValueError):
                raise OptimizeError("%s (%s %s): %s must be a number, got %r" % (what, item[0], item[1], key, value))
            if not math.isfinite(entry[key]):
                raise OptimizeError("%s (%s %s): %s must be finite, got %r" % (what, item[0], item[1], key, value))
        if "min" in entry and "max" in entry and not entry["min"] < entry["max"]:
            raise OptimizeError("%s (%s %s): min %g must be below max %g"
                                % (what, item[0], item[1], entry["min"], entry["max"]))
        return entry
    params = opts["parameters"]
    if params == "auto":
        job["parameters"] = "auto"
    else:
        if not params:
            raise OptimizeError("no design parameters chosen (pick faces, or use all parameters)")
        job["parameters"] = [design(p, "parameters[%d]" % i) for i, p in enumerate(params)]
    if opts["ties"]:
        job["ties"] = [[ref(p, "ties[%d]" % i) for p in tie] for i, tie in enumerate(opts["ties"])]
    if opts["fixed_faces"]:
        job["fixed_faces"] = [face_index(f, n, "fixed faces") for f in opts["fixed_faces"]]
    if opts.get("draft_faces"):
        pull = FreeCAD.Vector(*opts.get("draft_direction", (0.0, 0.0, 1.0)))
        if pull.Length < 1e-12:
            raise OptimizeError("the draft (pull) direction is zero")
        for f in opts["draft_faces"]:
            kind = shape.Faces[face_index(f, n, "draft faces")].Surface.TypeId
            if kind not in ("Part::GeomPlane", "Part::GeomCylinder", "Part::GeomCone"):
                raise OptimizeError("draft face %s is a %s: planes keep their normal orthogonal to the pull "
                                    "direction, cylinders and cones their axis parallel to it; no other surface"
                                    % (f, kind.replace("Part::Geom", "").lower()))
        d = (placement or FreeCAD.Placement()).inverse().Rotation.multVec(pull)  # into the part's frame
        job["orthogonal"] = [{"face": face_index(f, n, "draft faces"), "axis": [d.x, d.y, d.z]}
                             for f in opts["draft_faces"]]
    if opts.get("pattern_faces"):
        job["rotations"] = [pattern_rotation(shape, opts, placement)]
    if opts.get("mirror_faces"):
        job["mirrors"] = mirror_pairs(shape, opts, placement)
    if opts["supports"]:
        job["supports"] = [{"face": face_index(f, n, "supports")} for f in opts["supports"]]
    loaded = [face_index(f, n, "loads") for f in opts["loads"]]
    if loaded:
        area = sum(shape.Faces[i].Area for i in loaded)
        fx, fy, fz = opts["force"]
        if "loads" in objective.uses:
            # A total force per face (its share by area) stays that force on every model: a
            # traction per area would let the optimizer lower the load by shrinking the face.
            job["loads"] = [{"face": i, "force": [c * shape.Faces[i].Area / area for c in (fx, fy, fz)]}
                            for i in loaded]
        else:
            # The total force spread over the loaded faces by area (N/mm² = MPa), as in "Analyze part".
            job["loads"] = [{"face": i, "traction": [fx / area, fy / area, fz / area]} for i in loaded]
    if "material" in objective.uses:
        job["material"] = {"E": float(opts["E"]), "nu": float(opts["nu"]),
                           "density": float(opts["density"]) * 1e-12}
        if "supports" in objective.uses and not opts["supports"]:
            raise OptimizeError("objective '%s' needs supports: pick fixed faces" % objective.type)
        if "loads" in objective.uses and not loaded:
            raise OptimizeError("objective '%s' needs loads: pick loaded faces and a force" % objective.type)
        if opts.get("cells"):
            job["grid"] = {"cells": int(opts["cells"])}
        penalty = opts.get("nitsche_penalty", "fixed")
        if penalty not in ("fixed", "local"):
            raise OptimizeError("clamp penalty must be 'fixed' or 'local', got %r" % (penalty,))
        job["nitsche_penalty"] = penalty  # explicit: the engine's default depends on the element
    if opts.get("merge_penalty"):
        # Only compliance's gradient has the ties' term (resources/doc/optimization.md, "Pieces that join").
        if objective.type != "compliance":
            raise OptimizeError("smooth joins (merge penalty) need the compliance objective alone, got '%s'"
                                % objective.type)
        job["merge_penalty"] = True
    constraints = []
    volume = {}
    for key in ("max", "min"):
        ratio = opts.get(key + "_volume_ratio")
        if ratio:
            ratio = float(ratio)
            if not (math.isfinite(ratio) and ratio > 0):
                raise OptimizeError("volume bound: %s_ratio must be a positive ratio (0: none), got %r" % (key, ratio))
            volume[key + "_ratio"] = ratio
    if "min_ratio" in volume and "max_ratio" in volume and not volume["min_ratio"] <= volume["max_ratio"]:
        raise OptimizeError("volume bound: min ratio %g must not exceed max ratio %g"
                            % (volume["min_ratio"], volume["max_ratio"]))
    if volume:
        constraints.append(dict({"type": "volume"}, **volume))
    mass = mass_constraint(opts)
    if mass is not None:
        constraints.append(mass)
    if constraints:
        job["constraints"] = constraints
    return job


def default_output_dir(obj):
    """``<document folder>/<Document>_<Name>_optimize`` (the temp folder for unsaved documents)."""
    doc_file = obj.Document.FileName
    base = os.path.dirname(doc_file) if doc_file else tempfile.gettempdir()
    return os.path.join(base, "%s_%s_optimize" % (obj.Document.Name, obj.Name))


def prepare(obj, options, out_dir=None):
    """Check ``obj``, write ``part.brep`` and ``job.json`` into ``out_dir``; returns
    ``(part_path, job, job_path, out_dir, placement)``. Raises :class:`OptimizeError`."""
    shape, placement = _local_shape(obj)
    job = build_job(shape, options, placement)
    out_dir = out_dir or default_output_dir(obj)
    try:
        os.makedirs(out_dir, exist_ok=True)
        part = os.path.join(out_dir, "part.brep")
        shape.exportBrep(part)
        job_path = os.path.join(out_dir, "job.json")
        with open(job_path, "w") as f:
            json.dump(job, f, indent=1)
    except OSError as exc:
        raise OptimizeError("cannot write into %s: %s" % (out_dir, exc))
    return part, job, job_path, out_dir, placement


_RESULT_PROPERTIES = (
    # (type, name, tooltip, history key)
    ("App::PropertyString", "OptimizedFrom", "Name and label of the original solid", None),
    ("App::PropertyString", "Objective", "Objective type", "objective"),
    ("App::PropertyFloat", "InitialObjective", "Objective of the original", "initial_objective"),
    ("App::PropertyFloat", "FinalObjective", "Objective of the optimized solid", "final_objective"),
    ("App::PropertyInteger", "Iterations", "Optimizer iterations", None),
    ("App::PropertyInteger", "Evaluations", "Objective evaluations (valid models)", "evaluations"),
    ("App::PropertyInteger", "InvalidModels", "Rejected trial models (projection or B-rep update failed)",
     "invalid_models"),
    ("App::PropertyFloat", "VolumeRatio", "Final volume / initial volume", None),
    ("App::PropertyFloat", "TangencyResidual", "Largest tangency residual on the optimized part",
     "tangency_residual_max"),
    ("App::PropertyString", "OptimizationStatus", "Optimizer status and message", None),
    ("App::PropertyStringList", "ParameterChanges", "Design parameters (FreeCAD face names): initial -> final",
     None),
    ("App::PropertyPath", "HistoryFile", "history.json of the run", None),
    ("App::PropertyPath", "HistoryChart", "history.png: objective against iteration and time", None),
    ("App::PropertyPath", "BeforeAfterChart", "before_after.png: design parameters and objective before and after",
     None),
)

#: Added after :data:`_RESULT_PROPERTIES` only for a run with a mass bound (history.json has
#: ``initial_mass``): results of other runs, and of documents saved before mass bounds, have none
#: (read them with ``getattr``, see :func:`mass_summary`). Masses in kg (the job's unit, see
#: :data:`MASS_DENSITY_SCALE`).
_MASS_PROPERTIES = (
    ("App::PropertyFloat", "MaxMass", "Upper mass bound of the run [kg] (0: none)", None),
    ("App::PropertyFloat", "MinMass", "Lower mass bound of the run [kg] (0: none)", None),
    ("App::PropertyFloat", "Density", "Density of the mass bound [kg/m³] (history.json's density is in kg/mm³: × 1e-9)",
     None),
    ("App::PropertyFloat", "InitialMass", "Mass of the original [kg]: density [kg/mm³] × volume [mm³]", "initial_mass"),
    ("App::PropertyFloat", "FinalMass", "Mass of the optimized solid [kg]: density [kg/mm³] × volume [mm³]",
     "final_mass"),
)


#: Added after :data:`_RESULT_PROPERTIES` only for a run of the "target" objective (history.json
#: has ``initial_target_rms``): results of other runs, and of documents saved before it, have none
#: (read them with ``getattr``, see :func:`target_summary`). Distances in mm.
_TARGET_PROPERTIES = (
    ("App::PropertyString", "TargetFace", "The matched face (FreeCAD name; history.json's target_face is FaceN − 1)",
     None),
    ("App::PropertyFloat", "InitialTargetRms",
     "RMS distance [mm] of the original's matched face under the load from the target surface", "initial_target_rms"),
    ("App::PropertyFloat", "FinalTargetRms",
     "RMS distance [mm] of the optimized solid's matched face under the load from the target surface",
     "final_target_rms"),
    ("App::PropertyFloat", "InitialTargetMax", "Largest distance [mm] of the original's matched face under the load",
     "initial_target_max"),
    ("App::PropertyFloat", "FinalTargetMax",
     "Largest distance [mm] of the optimized solid's matched face under the load", "final_target_max"),
)


def _job_mass_bounds(out_dir):
    """``(max, min)`` [kg, 0: none] of the mass entry of ``out_dir/job.json`` (written by
    :func:`prepare` for both the in-process and the CLI route); ``(0, 0)`` when there is none."""
    try:
        with open(os.path.join(out_dir, "job.json")) as f:
            constraints = json.load(f).get("constraints", [])
    except (OSError, ValueError, AttributeError):
        return 0.0, 0.0
    for c in constraints:
        if isinstance(c, dict) and c.get("type") == "mass":
            return float(c.get("max", 0.0)), float(c.get("min", 0.0))
    return 0.0, 0.0


def add_result(obj, history, out_dir, placement=None):
    """Add the optimized solid (``out_dir/optimized.step``) as a new ``Part::Feature`` named
    ``<Label>_optimized`` beside ``obj`` with the history in read-only properties; returns it.

    Raises :class:`OptimizeError` (document unchanged) for a cancelled run, a missing or invalid
    result."""
    import Part
    status = history.get("status", "")
    if status in (CANCELLED, INTERRUPTED):
        where = history.get("optimized_step")
        raise OptimizeError("optimization cancelled by the user: the document is unchanged%s"
                            % ("; the best valid iterate so far is " + where if where else ""))
    step = history.get("optimized_step") or os.path.join(out_dir, "optimized.step")
    if not os.path.isfile(step):
        raise OptimizeError("the optimizer wrote no %s (status %s: %s)" % (step, status, history.get("message", "")))
    try:
        shape = Part.read(step)
    except Exception as exc:
        raise OptimizeError("cannot read %s: %s" % (step, exc))
    solids = shape.Solids
    if len(solids) != 1 or not solids[0].isValid():
        raise OptimizeError("%s is not one valid solid (%d solids)" % (step, len(solids)))
    solid = solids[0]
    try:
        from . import optimize_plot
        before_after = optimize_plot.plot_before_after(
            history, os.path.join(out_dir, optimize_plot.BEFORE_AFTER), obj.Label, freecad_parameter_name)
    except Exception as exc:  # the chart is optional: the history is complete without it
        FreeCAD.Console.PrintWarning("ParaFab: no before/after chart: %s\n" % exc)
        before_after = ""
    if placement is None:
        placement = solid_shape(obj).Placement
    doc = obj.Document
    new = doc.addObject("Part::Feature", obj.Name + "Optimized")
    try:
        new.Label = obj.Label + RESULT_SUFFIX
        new.Shape = solid
        new.Placement = placement
        values = {
            "OptimizedFrom": "%s (%s)" % (obj.Name, obj.Label),
            "Iterations": max(len(history.get("iterations", [])) - 1, 0),
            "VolumeRatio": (history["final_volume"] / history["initial_volume"]
                            if history.get("initial_volume") else 0.0),
            "OptimizationStatus": status if history.get("message", "") in ("", status)
            else "%s: %s" % (status, history["message"]),
            "ParameterChanges": ["%s %.6g -> %.6g" % (freecad_parameter_name(p["name"]), p["initial"], p["final"])
                                 for p in history.get("parameters", [])],
            "HistoryFile": os.path.join(out_dir, "history.json"),
            "HistoryChart": history.get("chart") or "",
            "BeforeAfterChart": before_after,
        }
        properties = _RESULT_PROPERTIES
        if history.get("initial_mass") is not None:
            properties += _MASS_PROPERTIES
            values["MaxMass"], values["MinMass"] = _job_mass_bounds(out_dir)
            values["Density"] = float(history.get("density") or 0.0) / MASS_DENSITY_SCALE
        if history.get("initial_target_rms") is not None:
            properties += _TARGET_PROPERTIES
            face = history.get("target_face")
            values["TargetFace"] = "Face%d" % (int(face) + 1) if face is not None else ""
        for prop_type, name, tip, key in properties:
            new.addProperty(prop_type, name, "Optimization", tip)
            value = values[name] if key is None else history.get(key)
            if value is not None:
                setattr(new, name, value)
            new.setEditorMode(name, 1)  # read-only
        original = _local_shape(obj)[0]  # the optimized solid is in the part's own frame too
        moved = face_changes(original, solid) if len(solid.Faces) == len(original.Faces) else []
        new.addProperty("App::PropertyFloatList", "FaceMoved", "Optimization",
                        "Per face (Face1, Face2, ...): how far its surface moved [mm], the largest distance of its "
                        "vertices and centre from the original face's surface (empty: the face count changed)")
        new.FaceMoved = moved
        new.setEditorMode("FaceMoved", 1)
        if FreeCAD.GuiUp and new.ViewObject is not None:
            show_face_changes(new)
            if obj.ViewObject is not None:
                obj.ViewObject.Transparency = 60
    except Exception:
        doc.removeObject(new.Name)
        raise
    doc.recompute()
    return new


#: Title (with the unit) of the colour scale of an optimized solid (:func:`show_face_changes`).
FACE_MOVED_TITLE = "Face moved [mm]"


def _distance_to_surface(surface, point):
    u, v = surface.parameter(point)
    return (surface.value(u, v) - point).Length


def face_changes(original, optimized):
    """Per face of ``optimized`` (same face order as ``original``, which optimization keeps): how
    far its surface moved [mm], the largest distance of its vertices and its parametric middle from
    the surface (not the bounded face: a neighbour's move may trim it) of the original's face of
    the same index. Both shapes in the same frame (the placement is the same); a face whose
    surface cannot be projected on counts by its vertices' distance to the original face."""
    out = []
    for before, after in zip(original.Faces, optimized.Faces):
        # Points ON the face: its vertices and its surface at the middle of its parameter range
        # (not its centre of mass, which for a whole cylinder lies on the axis, a radius away).
        u0, u1, v0, v1 = after.ParameterRange
        points = [v.Point for v in after.Vertexes] + [after.valueAt(0.5 * (u0 + u1), 0.5 * (v0 + v1))]
        try:
            surface = before.Surface
            distance = max(_distance_to_surface(surface, p) for p in points)
        except Exception:  # no projection: the bounded face (an upper bound of the surface's)
            import Part
            distance = max(before.distToShape(Part.Vertex(p))[0] for p in points)
        out.append(float(distance))
    return out


def show_face_changes(result):
    """Colour the faces of optimized solid ``result`` by ``FaceMoved`` (blue: unchanged, red: the
    largest move) and show the scale ``Face moved [mm]`` in the 3D view (GUI only). Without
    ``FaceMoved`` (the face count changed) the solid is plain green."""
    vobj = getattr(result, "ViewObject", None)
    if not FreeCAD.GuiUp or vobj is None:
        return
    from . import legend, result_display
    moved = list(getattr(result, "FaceMoved", []) or [])
    if not moved or len(moved) != len(result.Shape.Faces):
        vobj.ShapeColor = (0.35, 0.75, 0.45)
        legend.remove(vobj)
        return
    hi = max(moved)
    vobj.DiffuseColor = [c + (0.0,) for c in result_display.colors(moved, 0.0, hi)]
    legend.show(vobj, FACE_MOVED_TITLE, 0.0, hi, result_display.COLOR_STOPS)


def freecad_parameter_name(name):
    """The engine's ``"face 2 plane offset"`` (0-based) as FreeCAD names it: ``"Face3 plane offset"``."""
    m = re.match(r"face (\d+) (.*)$", name)
    return "Face%d %s" % (int(m.group(1)) + 1, m.group(2)) if m else name


def summary(history):
    """One line: objective, initial -> final, iterations, status."""
    return "%s %.4g -> %.4g in %d iterations (%s)" % (
        history.get("objective", ""), history.get("initial_objective", float("nan")),
        history.get("final_objective", float("nan")), max(len(history.get("iterations", [])) - 1, 0),
        history.get("status", ""))


def mass_summary(result):
    """``"mass 0.1497 -> 0.1495 kg (max 0.1495 kg)"`` of a result object of a run with a mass
    bound; ``""`` for any other (no mass properties, e.g. from a document saved before them)."""
    initial, final = getattr(result, "InitialMass", None), getattr(result, "FinalMass", None)
    if initial is None or final is None:
        return ""
    bounds = ["%s %.6g kg" % (k, v) for k, v in (("min", getattr(result, "MinMass", 0.0)),
                                                 ("max", getattr(result, "MaxMass", 0.0))) if v]
    return "mass %.6g -> %.6g kg%s" % (initial, final, " (%s)" % ", ".join(bounds) if bounds else "")


def target_summary(result):
    """``"target RMS 0.0924 -> 0.0106 mm (Face6)"`` of a result object of a "target" run; ``""``
    for any other (no target properties, e.g. from a document saved before them)."""
    initial, final = getattr(result, "InitialTargetRms", None), getattr(result, "FinalTargetRms", None)
    if initial is None or final is None:
        return ""
    face = getattr(result, "TargetFace", "")
    return "target RMS %.6g -> %.6g mm%s" % (initial, final, " (%s)" % face if face else "")


def optimize_shape(obj, job_options, out_dir=None, progress=None):
    """Optimize ``obj``'s solid in-process and add the result beside it.

    ``job_options``: see :func:`default_options`. ``progress(iterate)`` (``{iteration, objective,
    constraint_violation, seconds}``) may return False to cancel (nothing is added then).
    Returns ``{"object", "history", "out_dir", "job", "chart"}`` (``chart``: history.png; the
    object's ``BeforeAfterChart`` is before_after.png); raises :class:`OptimizeError`
    with the problem named, the document unchanged."""
    import parafab
    part, job, _, out_dir, placement = prepare(obj, job_options, out_dir)
    try:
        history = parafab.optimize(part, job, out_dir=out_dir, progress=progress)
    except Exception as exc:  # parafab.Error (bad job, bad part) and internal errors
        raise OptimizeError("optimization of %s failed: %s" % (obj.Label, exc))
    new = add_result(obj, history, out_dir, placement)
    return {"object": new, "history": history, "out_dir": out_dir, "job": job, "chart": history.get("chart")}
