#!/usr/bin/env bash
# Regenerates the README's "Results" section from real runs (no hand-typed numbers):
#   synthetic benchmarks: configs/paper.json vs paper_nn.json vs paper_ism.json on benchmarks/synthetic.json
#                         (objects outside the training catalog) and benchmarks/synthetic_catalog.json
#                         (training-catalog objects: fitting accuracy, per-object errors)
#   ScanNet dev set:     configs/scannet.json vs scannet_nn.json vs scannet_ism.json on benchmarks/scannet_dev.json
# Full reports, PR plots and run records go to runs/results/{synthetic,synthetic_catalog,scannet}/
# (git-ignored); the reports and PR plots are copied to docs/results/ (tracked, linked from the README).
set -euo pipefail
cd "$(dirname "$0")/.."
FURNIHOST=${FURNIHOST:-build/bin/furnihost}
OUT=${OUT:-runs/results}
"$FURNIHOST" eval --graph configs/paper.json --graph configs/paper_nn.json --graph configs/paper_ism.json \
  --dataset benchmarks/synthetic.json --out "$OUT/synthetic" -q
"$FURNIHOST" eval --graph configs/paper.json --graph configs/paper_nn.json --graph configs/paper_ism.json \
  --dataset benchmarks/synthetic_catalog.json --out "$OUT/synthetic_catalog" -q
"$FURNIHOST" eval --graph configs/scannet.json --graph configs/scannet_nn.json --graph configs/scannet_ism.json \
  --dataset benchmarks/scannet_dev.json --out "$OUT/scannet" -q
for set in synthetic synthetic_catalog scannet; do
  mkdir -p "docs/results/$set"
  cp "$OUT/$set/report.md" "$OUT/$set"/pr_*.png "docs/results/$set/"
done
python3 - "$OUT" <<'PY'
import re, sys, pathlib
out = pathlib.Path(sys.argv[1])
def tables(report):
    text = (out / report / "report.md").read_text()
    keep, on = [], False
    for line in text.splitlines():
        if line.startswith("## Detection"): on = True; continue
        if on and line.startswith("## "): break
        if on and line.startswith("### per object"): on = False; continue
        if on and (line.startswith("|") or line.startswith("### ")): keep.append(line.replace("### ", "**") + ("**" if line.startswith("### ") else ""))
        elif on and keep and keep[-1] != "": keep.append("")
    return "\n".join(keep)
block = ["<!-- results:begin (scripts/update_results.sh writes this section) -->",
         "Synthetic rooms (`benchmarks/synthetic.json`, objects not in the training catalog), "
         "A = paper.json, B = paper_nn.json, C = paper_ism.json:", "", tables("synthetic"), "",
         "Synthetic rooms of training-catalog models (`benchmarks/synthetic_catalog.json`; "
         "per-object centre and yaw errors in [docs/results/synthetic_catalog/report.md](docs/results/synthetic_catalog/report.md)), "
         "A = paper.json, B = paper_nn.json, C = paper_ism.json:", "", tables("synthetic_catalog"), "",
         "ScanNet dev scans (`benchmarks/scannet_dev.json`, trained on the shared CAD catalog only), "
         "A = scannet.json, B = scannet_nn.json, C = scannet_ism.json:", "", tables("scannet"), "",
         "Full reports (time per stage, peak memory, PR plots): [synthetic](docs/results/synthetic/report.md), "
         "[synthetic_catalog](docs/results/synthetic_catalog/report.md), [scannet](docs/results/scannet/report.md).",
         "<!-- results:end -->"]
readme = pathlib.Path("README.md")
text = readme.read_text()
new = re.sub(r"<!-- results:begin.*?<!-- results:end -->", "\n".join(block), text, flags=re.S)
tmp = readme.with_suffix(".md.tmp"); tmp.write_text(new); tmp.replace(readme)
print("README.md results updated from", out)
PY
