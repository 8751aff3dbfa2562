#!/usr/bin/python3
"""Conforming-FEM reference route: STEP -> gmsh tet mesh -> CalculiX (ccx) -> JSON.

Independent reference for validating the XFEM simulator (thesis ch. 6.4,
"Validation against CalculiX on a Gmsh tetrahedral mesh of the same STEP part").
Only needs Debian's /usr/bin/python3 + numpy and the Debian packages `gmsh`
(command line, no python API needed) and `calculix-ccx` (binary `ccx`).

Usage
-----
    /usr/bin/python3 calculix_reference.py job.json [-o result.json]
                                           [--workdir DIR] [--quiet]
    # same part + job as the XFEM simulator (`parafab simulate PART JOB`):
    /usr/bin/python3 calculix_reference.py samples/simulations/l_bracket.json \
        --parafab samples/parts/l_bracket.step --size 2 [--element C3D4]
    (--print-job shows the translated job; see from_parafab_job)

Units: the model is in mm, so use the consistent set mm / N / MPa / t/mm^3 / s
(steel: E = 210000 MPa, density = 7.85e-9 t/mm^3, g = 9810 mm/s^2).

Job format (JSON; keys not listed are ignored; relative paths are relative to
the job file)::

  {
    "step": "part.step",              # STEP file (geometry in mm)
    "mesh": {
      "size": 250.0,                  # gmsh -clmax (mm)
      "size_min": 0.0,                # optional gmsh -clmin (mm)
      "element": "C3D10",             # "C3D10" (tet10, default) or "C3D4" (tet4)
      "threads": 1,                   # optional gmsh -nt
      "fragment": false               # true: multi-solid STEP -> merge shared
    },                                #   faces (OCC Coherence) => conforming
    "material": {
      "model": "linear",              # "linear" | "neo_hooke" | "mooney_rivlin"
      "E": 210000.0, "nu": 0.3,       # MPa, -
      "density": 7.85e-9,             # optional, needed for "gravity"
      # hyperelastic only (else derived from E, nu: C10 = G/2, D1 = 2/K):
      "C10": ..., "C01": ..., "D1": ...
    },
    "boundary_conditions": [
      {"name": "clamp", "type": "fixed",
       "select": {"plane": {"axis": "x", "value": 0.0}}},
      {"name": "tip",   "type": "load", "force": [0, 0, -9e6],
       "distribution": "consistent",   # or "equal" (F / n_nodes per node)
       "select": {"plane": {"axis": "x", "value": 8000.0}}},
      {"name": "pull",  "type": "displacement", "value": [0.1, null, null],
       "select": {"surface": [3]}},      # null = component left free
      {"name": "g",     "type": "gravity", "acceleration": [0, 0, -9810.0]}
    ],
    "probes": [[8000, 500, 500]],          # points for "displacement_at"
    "probe_tol": 1e-3,                     # barycentric tolerance, else
                                           #   nearest node is reported
    "line": {"from": [0, 500, 1000], "to": [8000, 500, 1000], "n": 17},
    "solver": {"timeout": 900, "threads": 2, "nlgeom": false,
               "increment": [0.1, 1.0]}    # NLGEOM: initial, total time
  }

Selectors ("select" may also be a list of selectors -> union). All selectors
pick nodes on the boundary surface of the volume mesh unless
"boundary_only": false is given inside the selector.
  {"plane": {"axis": "x"|"y"|"z", "value": v, "tol": t}}     |x_axis - v| <= t
  {"box": {"min": [x,y,z], "max": [x,y,z]}}                   inclusive box
  {"surface": [tag, ...]}    gmsh B-rep surface tags (ELSET SurfaceN of gmsh;
                             = parafab/OCCT face index + 1)
  {"point": [x, y, z], "tol": t}   the whole B-rep face nearest the point
                             (like parafab's {"point"}); default tol
                             1e-3 * diagonal + size / 4 (chord sagitta)
  {"nodes": [id, ...]}       explicit mesh node ids
Default tol is 1e-6 * bounding-box diagonal (at least 1e-6 mm).

Loads: "force" is a total force; "traction": [tx, ty, tz] (per area) is
turned into force = traction * area of the selected faces. "consistent"
distributes the total force as a uniform traction
F / A over the boundary triangles whose nodes all lie in the selection
(A = their area) and integrates it with the element shape functions
(tri6: corners get 0, midside nodes A_tri/3; tri3: A_tri/3 per corner),
written as *CLOAD. If the selection contains no complete face it falls back to
"equal". Gravity uses *DLOAD, Eall, GRAV and requires "density".

Result JSON::

  {"status": "ok", "element_type": "C3D10", "nodes": n, "elements": m,
   "mesh_seconds": t, "solve_seconds": t, "total_seconds": t,
   "max_displacement": {"magnitude", "vector", "node", "position"},
   "displacement_at": [{"point", "u", "stress" [xx,yy,zz,xy,yz,zx],
                        "von_mises", "method": "interpolated"|"nearest_node",
                        "element"|"node", "distance"}],
   "von_mises": {"max", "node", "position"},       # nodal (extrapolated,
                                                   # averaged) ccx stresses
   "selections": {name: {"nodes", "faces", "area", "picked", "force",
                         "distribution"}},
   "reactions": {name: [Fx, Fy, Fz]},               # for fixed/displacement
   "compliance": f^T u,                             # if every load is a *CLOAD
   "line": {"points", "s", "u", "von_mises", "method"}, # if "line" given
   "ccx_warnings": [...],                            # if any
   "workdir": path or null, "versions": {...}}
Errors: {"status": "error", "error": message} and exit status 1.

Notes / pitfalls
  * gmsh's INP export contains every entity: T3D* line and CPS* surface
    elements besides the C3D4/C3D10 volume (when no physical groups exist);
    only volume elements go into the deck (surface ones give the B-rep tags).
    gmsh already writes C3D10 in Abaqus node order with positive volume.
  * .frd records are fixed width (I10 + E12.5, no separators when values
    are negative) and carry 5 digits; displacements are read from the .dat.
  * ccx's RF (reactions) omits loads applied directly on constrained nodes
    (e.g. gravity on the clamped face nodes).
  * Stresses are ccx's extrapolated + averaged nodal values; von Mises max is
    mesh dependent at re-entrant edges / clamped edges (singular).
  * multi-solid STEP: set mesh.fragment, otherwise solids are not connected
    (ccx solves without complaint; we refuse coincident nodes).
  * Hyperelastic models run *STEP, NLGEOM; stresses are then Cauchy.
"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

GMSH = os.environ.get("GMSH", "gmsh")
CCX = os.environ.get("CCX", "ccx")

AXES = {"x": 0, "y": 1, "z": 2}

# Abaqus/CalculiX C3D10 faces (0-based): 3 corners then the 3 midside nodes
# (edge c0-c1, c1-c2, c2-c0).  gmsh's INP writer already uses this ordering.
TET10_FACES = [(0, 1, 2, 4, 5, 6), (0, 3, 1, 7, 8, 4),
               (1, 3, 2, 8, 9, 5), (2, 3, 0, 9, 7, 6)]
TET4_FACES = [(0, 1, 2), (0, 3, 1), (1, 3, 2), (2, 3, 0)]
# tet10 edge midside nodes 4..9 -> corner pairs
TET10_EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]


class ReferenceError(RuntimeError):
    pass


# --------------------------------------------------------------------------
# meshing
# --------------------------------------------------------------------------
def run_gmsh(step, workdir, size, element, size_min=None, threads=None,
             timeout=900, fragment=False):
    order = 2 if element == "C3D10" else 1
    out = os.path.join(workdir, "mesh.inp")
    src = os.path.abspath(step)
    if fragment:
        # multi-solid STEP: imprint/merge shared faces so the mesh conforms
        src = os.path.join(workdir, "fragment.geo")
        with open(src, "w") as f:
            f.write('SetFactory("OpenCASCADE");\n'
                    'Geometry.OCCTargetUnit = "MM";\n'
                    'Merge "%s";\nCoherence;\n' % os.path.abspath(step))
    cmd = [GMSH, src, "-3", "-order", str(order),
           "-clmax", repr(float(size)),
           "-setstring", "Geometry.OCCTargetUnit", "MM",
           "-format", "inp", "-o", out]
    if size_min:
        cmd[5:5] = ["-clmin", repr(float(size_min))]
    if threads:
        cmd += ["-nt", str(int(threads))]
    p = subprocess.run(cmd, cwd=workdir, capture_output=True, text=True,
                       timeout=timeout)
    with open(os.path.join(workdir, "gmsh.log"), "w") as f:
        f.write(p.stdout + p.stderr)
    if p.returncode != 0 or not os.path.exists(out):
        raise ReferenceError("gmsh failed (rc=%d): %s" % (
            p.returncode, (p.stdout + p.stderr)[-2000:]))
    return out


def parse_gmsh_inp(path):
    """Parse gmsh's Abaqus .inp: nodes, volume elements, surface ELSETs.

    Returns (node_ids, coords, vol_type, vol_conn(node ids), surf) where
    surf maps gmsh surface tag -> list of its triangles (node ids; CPS3 or
    CPS6, corners first then midsides of edges 0-1, 1-2, 2-0).
    """
    ids, xyz = [], []
    vols = {"C3D4": [], "C3D10": []}
    surf = {}
    mode, cur, pending = None, None, []
    with open(path) as f:
        for line in f:
            if line.startswith("**"):
                continue
            if line.startswith("*"):
                u = line.upper().replace(" ", "")
                mode, cur = None, None
                if u.startswith("*NODE"):
                    mode = "node"
                elif u.startswith("*ELEMENT"):
                    m = re.search(r"TYPE=([A-Z0-9]+)", u)
                    es = re.search(r"ELSET=([A-Z0-9_]+)", u)
                    et = m.group(1) if m else ""
                    if et in vols:
                        mode, cur = "vol", vols[et]
                    elif es and es.group(1).startswith("SURFACE"):
                        tag = int(re.sub(r"\D", "", es.group(1)) or -1)
                        mode, cur = "surf", surf.setdefault(tag, [])
                continue
            if mode is None or not line.strip():
                continue
            vals = [v for v in line.replace(",", " ").split()]
            if mode == "node":
                ids.append(int(vals[0]))
                xyz.append([float(v) for v in vals[1:4]])
            elif mode == "vol":
                # gmsh writes one element per line; be tolerant of
                # continuation lines anyway (line ending with a comma)
                pending += [int(v) for v in vals]
                if not line.rstrip().endswith(","):
                    cur.append(pending)
                    pending = []
            elif mode == "surf":
                cur.append([int(v) for v in vals[1:]])
    if vols["C3D10"] and vols["C3D4"]:
        raise ReferenceError("mixed tet4/tet10 mesh")
    etype = "C3D10" if vols["C3D10"] else "C3D4"
    conn = np.array(vols[etype], dtype=np.int64)
    if conn.size == 0:
        raise ReferenceError("no volume elements in gmsh output")
    return (np.array(ids, dtype=np.int64), np.array(xyz, dtype=float),
            etype, conn, surf)


class Mesh:
    def __init__(self, ids, xyz, etype, conn, surf_sets):
        self.etype = etype
        self.el_ids = conn[:, 0]
        used = np.unique(conn[:, 1:])
        pos = {int(n): i for i, n in enumerate(ids)}
        idx = np.array([pos[int(n)] for n in used])
        self.node_ids = used                      # only nodes used by volumes
        self.xyz = xyz[idx]
        remap = np.full(int(ids.max()) + 1, -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        self.conn = remap[conn[:, 1:]]            # 0-based into self.xyz
        self.surf_sets, self.surf_tris = {}, {}
        for t, tris in surf_sets.items():
            r = remap[np.array(tris, dtype=np.int64)]
            self.surf_tris[t] = r[np.all(r >= 0, axis=1)]
            self.surf_sets[t] = np.unique(r[r >= 0])
        self._fix_orientation()
        self._boundary()
        lo, hi = self.xyz.min(0), self.xyz.max(0)
        self.diag = float(np.linalg.norm(hi - lo))
        # coincident nodes = solids meshed independently (multi-solid STEP
        # without "fragment"): ccx then solves silently with garbage
        q = np.round((self.xyz - lo) / max(1e-6 * self.diag, 1e-9))
        self.n_duplicate = int(len(q) - len(np.unique(q, axis=0)))
        self.point_tol = 1e-3 * self.diag     # "point" selector; see run_job
        self.point_picks = []

    def _fix_orientation(self):
        X = self.xyz[self.conn[:, :4]]
        v = np.einsum("ij,ij->i", np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]),
                      X[:, 3] - X[:, 0])
        neg = v < 0
        if neg.any():   # swap corners 1<->2 (and midsides accordingly)
            c = self.conn
            if self.etype == "C3D4":
                c[neg] = c[neg][:, [0, 2, 1, 3]]
            else:
                c[neg] = c[neg][:, [0, 2, 1, 3, 6, 5, 4, 7, 9, 8]]
        self.n_flipped = int(neg.sum())

    def _boundary(self):
        faces = TET10_FACES if self.etype == "C3D10" else TET4_FACES
        allf = np.concatenate([self.conn[:, list(f)] for f in faces])
        key = np.sort(allf[:, :3], axis=1)
        _, inv, cnt = np.unique(key, axis=0, return_inverse=True,
                                return_counts=True)
        self.bfaces = allf[cnt[inv.ravel()] == 1]
        self.bnodes = np.zeros(len(self.xyz), dtype=bool)
        self.bnodes[np.unique(self.bfaces)] = True

    # -- selections --------------------------------------------------------
    def select(self, sel):
        if isinstance(sel, list):
            m = np.zeros(len(self.xyz), dtype=bool)
            for s in sel:
                m |= self.select(s)
            return m
        boundary_only = sel.get("boundary_only", True)
        m = np.zeros(len(self.xyz), dtype=bool)
        tol_def = max(1e-6 * self.diag, 1e-6)
        if "plane" in sel:
            p = sel["plane"]
            a = AXES[p["axis"].lower()]
            tol = float(p.get("tol", tol_def))
            m = np.abs(self.xyz[:, a] - float(p["value"])) <= tol
        elif "box" in sel:
            b = sel["box"]
            tol = float(b.get("tol", tol_def))
            lo = np.array(b["min"], float) - tol
            hi = np.array(b["max"], float) + tol
            m = np.all((self.xyz >= lo) & (self.xyz <= hi), axis=1)
        elif "surface" in sel:
            tags = sel["surface"]
            tags = tags if isinstance(tags, list) else [tags]
            for t in tags:
                if int(t) not in self.surf_sets:
                    raise ReferenceError("gmsh surface %s not in mesh (have %s)"
                                         % (t, sorted(self.surf_sets)))
                m[self.surf_sets[int(t)]] = True
            boundary_only = False
        elif "point" in sel:
            t, d = self.surface_at(sel["point"])
            tol = float(sel.get("tol", self.point_tol))
            if d > tol:
                raise ReferenceError(
                    "no gmsh surface within %g of point %s (nearest: surface "
                    "%d at %g)" % (tol, sel["point"], t, d))
            m[self.surf_sets[t]] = True
            self.point_picks.append({"point": list(sel["point"]),
                                     "surface": int(t), "distance": d})
            boundary_only = False
        elif "nodes" in sel:
            pos = {int(n): i for i, n in enumerate(self.node_ids)}
            m[[pos[int(n)] for n in sel["nodes"]]] = True
            boundary_only = False
        else:
            raise ReferenceError("unknown selector %r" % (sel,))
        if boundary_only:
            m &= self.bnodes
        return m

    def surface_at(self, p):
        """(gmsh surface tag, distance) of the B-rep face nearest to p,
        measured to the straight-sided surface triangles."""
        best = (None, np.inf)
        for t, tris in self.surf_tris.items():
            if len(tris):
                d = point_triangle_distance(np.asarray(p, float),
                                            self.xyz[tris[:, :3]]).min()
                if d < best[1]:
                    best = (t, float(d))
        if best[0] is None:
            raise ReferenceError("mesh has no surface elements")
        return best

    def surface_areas(self):
        out = {}
        for t, tris in self.surf_tris.items():
            out[t] = self.face_shape_integrals(tris)[2] if len(tris) else 0.0
        return out

    def faces_in(self, mask):
        return self.bfaces[np.all(mask[self.bfaces], axis=1)]

    # -- consistent surface integration -------------------------------------
    def face_shape_integrals(self, faces):
        """Return (node_index array, weights = int N_i dA, total area)."""
        # 6-point degree-4 rule on the reference triangle (weights sum 1/2)
        a, b = 0.445948490915965, 0.091576213509771
        wa, wb = 0.223381589678011 / 2, 0.109951743655322 / 2
        pts = np.array([[a, a], [1 - 2 * a, a], [a, 1 - 2 * a],
                        [b, b], [1 - 2 * b, b], [b, 1 - 2 * b]])
        w = np.array([wa] * 3 + [wb] * 3)
        Xf = self.xyz[faces]                      # (nf, nn, 3)
        acc = np.zeros(faces.shape)
        for (r, s), wq in zip(pts, w):
            L = np.array([1 - r - s, r, s])
            if faces.shape[1] == 6:
                N = np.array([L[0] * (2 * L[0] - 1), L[1] * (2 * L[1] - 1),
                              L[2] * (2 * L[2] - 1), 4 * L[0] * L[1],
                              4 * L[1] * L[2], 4 * L[2] * L[0]])
                # dN/dr, dN/ds  (L0 = 1-r-s, L1 = r, L2 = s)
                dr = np.array([-(4 * L[0] - 1), 4 * L[1] - 1, 0,
                               4 * (L[0] - L[1]), 4 * L[2], -4 * L[2]])
                ds = np.array([-(4 * L[0] - 1), 0, 4 * L[2] - 1,
                               -4 * L[1], 4 * L[1], 4 * (L[0] - L[2])])
            else:
                N = L
                dr = np.array([-1.0, 1.0, 0.0])
                ds = np.array([-1.0, 0.0, 1.0])
            xr = np.einsum("n,fnk->fk", dr, Xf)
            xs = np.einsum("n,fnk->fk", ds, Xf)
            J = np.linalg.norm(np.cross(xr, xs), axis=1)
            acc += wq * J[:, None] * N[None, :]
        area = float(acc.sum())
        return faces.ravel(), acc.ravel(), area

    # -- point location ------------------------------------------------------
    def locate(self, p):
        """Return (element index, barycentric L0..L3) of the best tet."""
        if not hasattr(self, "_Tinv"):
            X = self.xyz[self.conn[:, :4]]
            T = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0],
                          X[:, 3] - X[:, 0]], axis=2)
            self._x0 = X[:, 0]
            self._Tinv = np.linalg.inv(T)
        lam = np.einsum("eij,ej->ei", self._Tinv, np.asarray(p) - self._x0)
        L = np.column_stack([1 - lam.sum(1), lam])
        e = int(np.argmax(L.min(1)))
        return e, L[e], float(L[e].min())

    def interpolate(self, e, L, field):
        """Evaluate a nodal field in element e at barycentric coords L."""
        if self.etype == "C3D4":
            N = L
        else:
            N = np.concatenate([L * (2 * L - 1),
                                [4 * L[i] * L[j] for i, j in TET10_EDGES]])
        return N @ field[self.conn[e]]


def point_triangle_distance(p, T):
    """Distance from point p to each triangle T[k] = (a, b, c) (vectorised,
    Ericson, Real-Time Collision Detection 5.1.5)."""
    a, b, c = T[:, 0], T[:, 1], T[:, 2]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        den = va + vb + vc
        v, w = vb / den, vc / den                        # interior
        q = a + ab * v[:, None] + ac * w[:, None]
        # edge regions
        e_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        t = d1 / (d1 - d3)
        q = np.where(e_ab[:, None], a + ab * t[:, None], q)
        e_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        t = d2 / (d2 - d6)
        q = np.where(e_ac[:, None], a + ac * t[:, None], q)
        e_bc = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        q = np.where(e_bc[:, None], b + (c - b) * t[:, None], q)
    # vertex regions
    q = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, q)
    q = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, q)
    q = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, q)
    return np.linalg.norm(p - q, axis=1)


# --------------------------------------------------------------------------
# CalculiX deck
# --------------------------------------------------------------------------
def _ids(lst, per_line=16):
    lst = list(lst)
    return "\n".join(", ".join(str(int(v)) for v in lst[i:i + per_line])
                     for i in range(0, len(lst), per_line))


def write_deck(mesh, job, path):
    mat = job.get("material", {})
    model = mat.get("model", "linear").lower()
    E, nu = float(mat.get("E", 210000.0)), float(mat.get("nu", 0.3))
    solver = job.get("solver", {})
    bcs = job.get("boundary_conditions", [])
    selections, info = {}, {}
    out = ["*HEADING", "ParaFab CalculiX reference (generated)", "*NODE"]
    out += ["%d, %.12g, %.12g, %.12g" % (n, *x)
            for n, x in zip(mesh.node_ids, mesh.xyz)]
    out.append("*ELEMENT, TYPE=%s, ELSET=Eall" % mesh.etype)
    nid = mesh.node_ids
    for eid, c in zip(mesh.el_ids, mesh.conn):
        out.append("%d, %s" % (eid, ", ".join(str(int(v)) for v in nid[c])))
    out.append("*NSET, NSET=Nall")
    out.append(_ids(nid))

    for k, bc in enumerate(bcs):
        t = bc["type"].lower()
        name = re.sub(r"[^A-Za-z0-9_]", "_", bc.get("name", "bc%d" % k))[:70]
        bc["_set"] = name
        if t == "gravity":
            continue
        mesh.point_picks = []
        m = mesh.select(bc["select"])
        picks = list(mesh.point_picks)
        if not m.any():
            raise ReferenceError("selection of %r is empty" % name)
        faces = mesh.faces_in(m)
        selections[name] = m
        info[name] = {"nodes": int(m.sum()), "faces": int(len(faces)),
                      "area": (mesh.face_shape_integrals(faces)[2]
                               if len(faces) else 0.0)}
        if picks:
            info[name]["picked"] = picks
        out.append("*NSET, NSET=%s" % name)
        out.append(_ids(nid[m]))

    out += ["*MATERIAL, NAME=MAT"]
    if model == "linear":
        out += ["*ELASTIC", "%.12g, %.12g" % (E, nu)]
    else:
        G, K = E / (2 * (1 + nu)), E / (3 * (1 - 2 * nu))
        C10 = float(mat.get("C10", G / 2))
        C01 = float(mat.get("C01", 0.0))
        D1 = float(mat.get("D1", 2.0 / K))
        if model in ("neo_hooke", "neohooke", "neo-hooke"):
            out += ["*HYPERELASTIC, NEO HOOKE", "%.12g, %.12g" % (C10, D1)]
        elif model in ("mooney_rivlin", "mooney-rivlin"):
            if "C10" not in mat:      # split G/2 between C10 and C01
                C10, C01 = G / 4, G / 4
            out += ["*HYPERELASTIC, MOONEY-RIVLIN",
                    "%.12g, %.12g, %.12g" % (C10, C01, D1)]
        else:
            raise ReferenceError("unknown material model %r" % model)
    if "density" in mat:
        out += ["*DENSITY", "%.12g" % float(mat["density"])]
    out += ["*SOLID SECTION, ELSET=Eall, MATERIAL=MAT"]

    nlgeom = bool(solver.get("nlgeom", model != "linear"))
    if nlgeom:
        inc = solver.get("increment", [0.1, 1.0])
        out += ["*STEP, NLGEOM, INC=%d" % int(solver.get("max_increments", 200)),
                "*STATIC", "%.6g, %.6g" % (inc[0], inc[1])]
    else:
        out += ["*STEP", "*STATIC"]

    bnd, cl, dl = [], {}, []
    for bc in bcs:
        t, name = bc["type"].lower(), bc["_set"]
        if t == "fixed":
            bnd.append("%s, 1, 3" % name)
        elif t == "displacement":
            for d, v in enumerate(bc["value"]):
                if v is not None:
                    bnd.append("%s, %d, %d, %.12g" % (name, d + 1, d + 1, v))
        elif t == "load":
            m = selections[name]
            faces = mesh.faces_in(m)
            if "traction" in bc:        # per unit area -> total force
                F = np.asarray(bc["traction"], float) * info[name]["area"]
                if not len(faces):
                    raise ReferenceError("traction on %r: no faces" % name)
            else:
                F = np.asarray(bc["force"], float)
            info[name]["force"] = F.tolist()
            dist = bc.get("distribution", "consistent").lower()
            if dist in ("consistent", "area") and len(faces):
                nodes, wts, area = mesh.face_shape_integrals(faces)
                share = np.bincount(nodes, wts, minlength=len(mesh.xyz)) / area
            else:
                dist = "equal"
                share = m / m.sum()
            info[name]["distribution"] = dist
            for i in np.nonzero(share)[0]:
                cl.setdefault(i, np.zeros(3))
                cl[i] += share[i] * F
        elif t == "gravity":
            if "density" not in mat:
                raise ReferenceError("gravity needs material.density")
            g = np.asarray(bc["acceleration"], float)
            mag = float(np.linalg.norm(g))
            dl.append("Eall, GRAV, %.12g, %.12g, %.12g, %.12g"
                      % (mag, *(g / mag)))
        else:
            raise ReferenceError("unknown bc type %r" % t)
    if bnd:
        out += ["*BOUNDARY"] + bnd
    if cl:
        ftot = max(np.abs(v).max() for v in cl.values())
        out.append("*CLOAD")
        for i in sorted(cl):
            for d in range(3):
                if abs(cl[i][d]) > 1e-12 * ftot:
                    out.append("%d, %d, %.12g" % (nid[i], d + 1, cl[i][d]))
    if dl:
        out += ["*DLOAD"] + dl
    # the nodal loads (mesh index -> force) for the compliance f^T u (none with a *DLOAD)
    mesh.cloads = None if dl else {i: np.asarray(cl[i], float) for i in cl}
    out += ["*NODE FILE", "U", "*EL FILE", "S"]
    # .frd values have only 5 significant digits (E12.5); the .dat print
    # (E13.6) is used for displacements when present.
    if solver.get("dat_displacements", True):
        out += ["*NODE PRINT, NSET=Nall", "U"]
    for bc in bcs:
        if bc["type"].lower() in ("fixed", "displacement"):
            out += ["*NODE PRINT, NSET=%s, TOTALS=ONLY" % bc["_set"], "RF"]
    out.append("*END STEP")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")
    return info


# --------------------------------------------------------------------------
# ccx run + output parsing
# --------------------------------------------------------------------------
def run_ccx(workdir, jobname, timeout, threads):
    env = dict(os.environ)
    if threads:
        env["OMP_NUM_THREADS"] = str(threads)
        env["CCX_NPROC_EQUATION_SOLVER"] = str(threads)
    p = subprocess.run([CCX, "-i", jobname], cwd=workdir, capture_output=True,
                       text=True, timeout=timeout, env=env)
    log = p.stdout + p.stderr
    with open(os.path.join(workdir, "ccx.log"), "w") as f:
        f.write(log)
    frd = os.path.join(workdir, jobname + ".frd")
    if p.returncode != 0 or "*ERROR" in log or not os.path.exists(frd):
        raise ReferenceError("ccx failed (rc=%d): %s" % (p.returncode,
                                                         log[-3000:]))
    return frd, log


def parse_frd(path):
    """Last DISP and STRESS nodal blocks of an ASCII .frd.

    Records are fixed width: ' -1' + node id (I10) + values (E12.5), so
    values can touch each other ('-1.23E+00-4.56E+00'); never split().
    """
    blocks, cur, name = {}, None, None
    with open(path) as f:
        for line in f:
            if line.startswith(" -4"):
                name = line[5:13].strip()
                cur = {}
                blocks[name] = cur          # later steps/increments overwrite
            elif line.startswith(" -1") and cur is not None:
                n = int(line[3:13])
                vals = [float(line[13 + 12 * k:25 + 12 * k])
                        for k in range((len(line.rstrip("\n")) - 13) // 12)]
                cur[n] = vals
            elif line.startswith(" -3"):
                cur = None
    return blocks


def parse_dat(path):
    """Parse the .dat: returns (totals {SET: [fx,fy,fz]}, displacements
    {node: [ux,uy,uz]}); later increments overwrite earlier ones.

    Blocks look like
     ' total force (fx,fy,fz) for set CLAMP and time  0.1000000E+01'
     ' displacements (vx,vy,vz) for set NALL and time  0.1000000E+01'
    followed by a blank line and whitespace separated numbers (E13.6 with a
    leading blank, so split() is safe here, unlike the .frd).
    """
    tot, disp, mode, name = {}, {}, None, None
    if not os.path.exists(path):
        return tot, disp
    with open(path) as f:
        for line in f:
            m = re.search(r"total force \(fx,fy,fz\) for set (\S+)", line)
            if m:
                mode, name = "tot", m.group(1)
                continue
            if re.search(r"displacements \(vx,vy,vz\) for set", line):
                mode = "disp"
                disp = {}
                continue
            if not line.strip():
                continue
            v = line.split()
            if mode == "tot":
                tot[name] = [float(x) for x in v[:3]]
                mode = None
            elif mode == "disp":
                try:
                    disp[int(v[0])] = [float(x) for x in v[1:4]]
                except ValueError:
                    mode = None
            # any other block header ends the current block
            if line[:1] == " " and v and v[0].isalpha():
                mode = None
    return tot, disp


def von_mises(s):
    sxx, syy, szz, sxy, syz, szx = s.T
    return np.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2)
                   + 3 * (sxy ** 2 + syz ** 2 + szx ** 2))


def _versions():
    v = {}
    try:
        p = subprocess.run([GMSH, "--version"], capture_output=True, text=True)
        v["gmsh"] = (p.stdout + p.stderr).strip()
    except OSError:
        pass
    try:
        p = subprocess.run([CCX, "-v"], capture_output=True, text=True)
        m = re.search(r"Version\s+(\S+)", p.stdout + p.stderr)
        v["ccx"] = m.group(1) if m else None
    except OSError:
        pass
    return v


def make_box_step(path, size, origin=(0.0, 0.0, 0.0)):
    """Write a box STEP (mm) with gmsh's OpenCASCADE kernel (for tests)."""
    path = os.path.abspath(path)
    d = tempfile.mkdtemp(prefix="ccxref_geo_")
    try:
        geo = os.path.join(d, "box.geo")
        with open(geo, "w") as f:
            f.write('SetFactory("OpenCASCADE");\nBox(1) = {%s};\n'
                    % ", ".join(repr(float(v)) for v in (*origin, *size)))
        p = subprocess.run([GMSH, geo, "-0", "-format", "step", "-o", path],
                           capture_output=True, text=True, timeout=120)
        if p.returncode != 0 or not os.path.exists(path):
            raise ReferenceError("gmsh STEP export failed: " + p.stdout[-1000:])
    finally:
        shutil.rmtree(d, ignore_errors=True)
    return path


# --------------------------------------------------------------------------
def run_job(job, base_dir=".", workdir=None, log=None):
    t0 = time.time()
    own_tmp = workdir is None
    wd = tempfile.mkdtemp(prefix="ccxref_") if own_tmp else workdir
    os.makedirs(wd, exist_ok=True)
    try:
        step = job["step"]
        if not os.path.isabs(step):
            step = os.path.join(base_dir, step)
        if not os.path.exists(step):
            raise ReferenceError("STEP file not found: %s" % step)
        mcfg = job.get("mesh", {})
        etype = mcfg.get("element", "C3D10").upper()
        etype = {"TET10": "C3D10", "TET4": "C3D4"}.get(etype, etype)
        if etype not in ("C3D10", "C3D4"):
            raise ReferenceError("element must be C3D10 or C3D4")
        scfg = job.get("solver", {})
        timeout = float(scfg.get("timeout", 900))

        inp = run_gmsh(step, wd, mcfg["size"], etype, mcfg.get("size_min"),
                       mcfg.get("threads"), timeout,
                       bool(mcfg.get("fragment", False)))
        mesh = Mesh(*parse_gmsh_inp(inp))
        # "point" picks measure to straight-sided triangles: allow the chord
        # sagitta of curved faces
        mesh.point_tol = float(job.get("point_tol",
                                       1e-3 * mesh.diag + 0.25 * mcfg["size"]))
        if mesh.n_duplicate and not mcfg.get("allow_duplicate_nodes"):
            raise ReferenceError(
                "%d coincident mesh nodes: the STEP has several solids that "
                "were meshed independently; set mesh.fragment = true"
                % mesh.n_duplicate)
        t_mesh = time.time() - t0
        if log:
            log("mesh: %d nodes, %d %s elements (%.2f s)"
                % (len(mesh.xyz), len(mesh.conn), etype, t_mesh))

        info = write_deck(mesh, job, os.path.join(wd, "job.inp"))
        t1 = time.time()
        frd, ccx_log = run_ccx(wd, "job", timeout, scfg.get("threads"))
        warnings = [ln.strip() for ln in ccx_log.splitlines()
                    if "WARNING" in ln.upper()][:20]
        t_solve = time.time() - t1
        if log:
            log("ccx: %.2f s" % t_solve)

        names = {bc["_set"].upper(): bc.get("name", bc["_set"])
                 for bc in job.get("boundary_conditions", [])}
        blocks = parse_frd(frd)
        pos = {int(n): i for i, n in enumerate(mesh.node_ids)}
        U = np.zeros((len(mesh.xyz), 3))
        for n, v in blocks.get("DISP", {}).items():
            if n in pos:
                U[pos[n]] = v[:3]
        S = np.zeros((len(mesh.xyz), 6))
        for n, v in blocks.get("STRESS", {}).items():
            if n in pos:
                S[pos[n]] = v[:6]
        if "DISP" not in blocks:
            raise ReferenceError("no DISP block in %s" % frd)
        totals, udat = parse_dat(os.path.join(wd, "job.dat"))
        for n, v in udat.items():
            if n in pos:
                U[pos[n]] = v
        vm = von_mises(S)
        SV = np.column_stack([S, vm])
        umag = np.linalg.norm(U, axis=1)
        imax, ivm = int(np.argmax(umag)), int(np.argmax(vm))

        # barycentric tolerance: points on curved faces lie slightly outside
        # the straight-sided corner tets; beyond it use the nearest node
        probe_tol = float(job.get("probe_tol", 1e-3))

        def probe(p):
            p = np.asarray(p, float)
            e, L, lmin = mesh.locate(p)
            if lmin >= -probe_tol:
                sv = mesh.interpolate(e, L, SV)
                return {"point": p.tolist(), "method": "interpolated",
                        "element": int(mesh.el_ids[e]),
                        "u": mesh.interpolate(e, L, U).tolist(),
                        "stress": sv[:6].tolist(),
                        "von_mises": float(sv[6])}
            i = int(np.argmin(np.linalg.norm(mesh.xyz - p, axis=1)))
            return {"point": p.tolist(), "method": "nearest_node",
                    "node": int(mesh.node_ids[i]),
                    "distance": float(np.linalg.norm(mesh.xyz[i] - p)),
                    "u": U[i].tolist(), "stress": S[i].tolist(),
                    "von_mises": float(vm[i])}

        res = {
            "status": "ok",
            "element_type": etype,
            "nodes": int(len(mesh.xyz)),
            "elements": int(len(mesh.conn)),
            "mesh_size": float(mcfg["size"]),
            "mesh_seconds": round(t_mesh, 3),
            "solve_seconds": round(t_solve, 3),
            "max_displacement": {"magnitude": float(umag[imax]),
                                 "vector": U[imax].tolist(),
                                 "node": int(mesh.node_ids[imax]),
                                 "position": mesh.xyz[imax].tolist()},
            "displacement_at": [probe(p) for p in job.get("probes", [])],
            "von_mises": {"max": float(vm[ivm]),
                          "node": int(mesh.node_ids[ivm]),
                          "position": mesh.xyz[ivm].tolist()},
            "selections": info,
            # ccx upper-cases set names in the .dat; map back to job names
            "reactions": {names.get(k, k): v for k, v in totals.items()},
        }
        if getattr(mesh, "cloads", None):
            # compliance f^T u of the nodal loads (only when every load is a *CLOAD)
            res["compliance"] = float(sum(F @ U[i] for i, F in mesh.cloads.items()))
        if warnings:
            res["ccx_warnings"] = warnings
        if mesh.n_flipped:
            res["flipped_elements"] = mesh.n_flipped
        if "line" in job:
            ln = job["line"]
            a, b = np.asarray(ln["from"], float), np.asarray(ln["to"], float)
            n = int(ln.get("n", 21))
            pts = [a + (b - a) * k / (n - 1) for k in range(n)]
            samples = [probe(p) for p in pts]
            res["line"] = {"points": [p.tolist() for p in pts],
                           "s": [float(np.linalg.norm(p - a)) for p in pts],
                           "u": [s["u"] for s in samples],
                           "von_mises": [s["von_mises"] for s in samples],
                           "method": [s["method"] for s in samples]}
        res["versions"] = _versions()
        res["workdir"] = None if own_tmp else os.path.abspath(wd)
        res["total_seconds"] = round(time.time() - t0, 3)
        return res
    finally:
        if own_tmp:
            shutil.rmtree(wd, ignore_errors=True)


def from_parafab_job(pjob, step, size, element="C3D10"):
    """Translate a `parafab simulate` job (samples/simulations/*.json) into a
    reference job for the same STEP part.

    supports[i] {"face": k | "point": p [, "displacement": d]} -> fixed /
    displacement on that B-rep face; loads[i] {"face"|"point", "force" (total,
    spread as uniform traction) | "traction"} -> load; gravity -> gravity
    (only if material.density > 0, as in parafab); probes -> probes.
    parafab face index k (OCCT TopExp order, 0-based) is gmsh surface tag
    k + 1 (both come from OCCT's face map; checked by area on the samples).
    """
    if "solid" in pjob:
        raise ReferenceError("parafab job selects a solid; not supported")

    def sel(item, path):
        if "face" in item:
            return {"surface": [int(item["face"]) + 1]}
        if "point" in item:
            return {"point": list(item["point"])}
        raise ReferenceError(path + " needs face or point")

    m = pjob.get("material", {})
    job = {"step": os.path.abspath(step),
           "mesh": {"size": float(size), "element": element},
           "material": {"E": m["E"], "nu": m.get("nu", 0.3)},
           "boundary_conditions": [],
           "probes": pjob.get("probes", [])}
    if m.get("density"):
        job["material"]["density"] = m["density"]
    for i, sp in enumerate(pjob.get("supports", [])):
        bc = {"name": "support%d" % i, "select": sel(sp, "supports[%d]" % i)}
        if "displacement" in sp and any(sp["displacement"]):
            bc.update(type="displacement", value=list(sp["displacement"]))
        else:
            bc["type"] = "fixed"
        job["boundary_conditions"].append(bc)
    for i, ld in enumerate(pjob.get("loads", [])):
        bc = {"name": "load%d" % i, "type": "load",
              "select": sel(ld, "loads[%d]" % i)}
        if "traction" in ld:
            bc["traction"] = list(ld["traction"])
        else:
            bc["force"] = list(ld["force"])
        job["boundary_conditions"].append(bc)
    if "gravity" in pjob and m.get("density"):
        job["boundary_conditions"].append(
            {"name": "gravity", "type": "gravity",
             "acceleration": list(pjob["gravity"])})
    return job


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("job", help="job JSON file (this format, or a parafab "
                    "simulate job with --parafab)")
    ap.add_argument("-o", "--output", help="result JSON (default stdout)")
    ap.add_argument("--workdir", help="keep gmsh/ccx files in this directory")
    ap.add_argument("--quiet", action="store_true")
    ap.add_argument("--parafab", metavar="STEP",
                    help="job is a `parafab simulate` job for this STEP part")
    ap.add_argument("--size", type=float, help="mesh size (mm), --parafab")
    ap.add_argument("--element", default="C3D10", help="C3D10|C3D4, --parafab")
    ap.add_argument("--print-job", action="store_true",
                    help="print the (translated) job and exit")
    a = ap.parse_args(argv)
    with open(a.job) as f:
        job = json.load(f)
    log = None if a.quiet else (lambda s: print(s, file=sys.stderr))
    try:
        if a.parafab:
            if not a.size:
                ap.error("--parafab needs --size")
            job = from_parafab_job(job, a.parafab, a.size, a.element)
        if a.print_job:
            print(json.dumps(job, indent=1))
            return 0
        res = run_job(job, os.path.dirname(os.path.abspath(a.job)),
                      a.workdir, log)
    except (ReferenceError, subprocess.TimeoutExpired) as e:
        res = {"status": "error", "error": str(e)}
    txt = json.dumps(res, indent=1)
    if a.output:
        with open(a.output, "w") as f:
            f.write(txt + "\n")
    else:
        print(txt)
    return 0 if res["status"] == "ok" else 1


if __name__ == "__main__":
    sys.exit(main())
