"""Cut sheets for every feasible strip result in a folder (run by .ci/main.sh):
<name>.result.json -> <name>.dxf and <name>.svg (flat outline in mm, see
parafab.export_strip_outline). Usage: export_cut_sheets.py RESULTS_DIR MODULE_DIR
"""
import glob
import json
import os
import sys

sys.path.insert(0, sys.argv[2])
import parafab  # noqa: E402

for path in sorted(glob.glob(os.path.join(sys.argv[1], "*.result.json"))):
    with open(path) as f:
        result = json.load(f)
    name = path[: -len(".result.json")]
    result.setdefault("name", os.path.basename(name))
    if not result.get("feasible"):
        print("cut sheet %-26s skipped (infeasible)" % os.path.basename(name))
        continue
    for ext in ("dxf", "svg"):
        parafab.export_strip_outline(result, name + "." + ext)
    sim = result.get("simulation")
    print("cut sheet %-26s L = %.2f mm, width %.2f..%.2f mm, R = %.4f%s" % (
        os.path.basename(name), 1e3 * result["length"], 1e3 * min(result["width"]),
        1e3 * max(result["width"]), result["R"],
        ", simulated deviation %.2e" % sim["deviation"] if sim else ""))
