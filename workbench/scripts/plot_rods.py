"""PNG twist plots of rod results: tau_beta(s), beta(s), semi-axes (Debian's matplotlib).
Usage: /usr/bin/python3 plot_rods.py DIR   (reads DIR/*.result.json, writes DIR/*.png)"""
import glob
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "freecad", "ParaFab"))
from parafab_wb.rod_plot import plot_rod  # noqa: E402

for path in sorted(glob.glob(os.path.join(sys.argv[1], "*.result.json"))):
    name = os.path.basename(path)[: -len(".result.json")]
    print(plot_rod(json.load(open(path)), os.path.join(sys.argv[1], name + ".png"), name))
