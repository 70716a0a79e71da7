"""Solves mrf_grid_v1 problems (shared/formats/mrf.md) with GCO 3.0 and with Motif, interleaved.

Run through scripts/bench-gco.sh, which prepares the Python environment. GCO gets the same
problem Motif reads: a general graph with the grid's 6- or 26-neighbourhood, the unary table, the
label cost matrix times the edge weight, the argmin labelling as start, and `expansion(-1)` (GCO's
default schedule, which Motif's `--cycles queue` follows). Times are GCO's thread CPU time around
`gcoExpansion` and Motif's `solve_ms` (wall clock of the solve; CPU time with --threads 1).
Motif runs as it does by default (flow recycling: each label's move graph kept between its
moves) and, on one thread, with `--no-recycle` (every move's graph built anew, as GCO does).
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

# gco-wrapper 3.0.9 still names numpy aliases removed in numpy 1.24.
for alias, real in (("int", int), ("float", float)):
    if not hasattr(np, alias):
        setattr(np, alias, real)
if not hasattr(np, "float128"):
    np.float128 = np.longdouble
from gco.cgco import _cgco  # noqa: E402


def grid_edges(dims, connectivity):
    """Edges (p, q) of the grid, p < q in the lexicographically positive directions."""
    nx, ny, nz = dims
    # mrf_grid_v1 site index (x ny + y) nz + z: z is fastest.
    idx = np.arange(nx * ny * nz).reshape(nx, ny, nz)
    if connectivity == 6:
        dirs = [(1, 0, 0), (0, 1, 0), (0, 0, 1)]
    else:
        dirs = [d for d in ((x, y, z) for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1))
                if d > (0, 0, 0)]
    first, second = [], []
    for d in dirs:
        src = tuple(slice(max(0, -c), n - max(0, c)) for c, n in zip(d, dims))
        dst = tuple(slice(max(0, c), n + min(0, c)) for c, n in zip(d, dims))
        first.append(idx[src].ravel())
        second.append(idx[dst].ravel())
    return np.concatenate(first).astype(np.intc), np.concatenate(second).astype(np.intc)


def gco_solve(problem):
    dims, labels = problem["dims"], problem["num_labels"]
    n = dims[0] * dims[1] * dims[2]
    unary = np.ascontiguousarray(np.array(problem["unary"], dtype=np.intc).reshape(n, labels))
    pairwise = np.ascontiguousarray(np.array(problem["pairwise"], dtype=np.intc).reshape(labels, labels))
    weight = problem.get("edge_weight", 1)
    a, b = grid_edges(dims, problem["connectivity"])
    start = np.argmin(unary, axis=1)
    handle = np.empty(1, dtype=np.intc)
    _cgco.gcoCreateGeneralGraph(np.intc(n), np.intc(labels), handle)
    h = handle[0]
    try:
        _cgco.gcoSetDataCost(h, unary)
        _cgco.gcoSetAllNeighbors(h, a, b, np.full(len(a), weight, dtype=np.intc), np.intc(len(a)))
        _cgco.gcoSetSmoothCost(h, pairwise)
        for p in range(n):
            _cgco.gcoInitLabelAtSite(h, np.intc(p), np.intc(start[p]))
        energy = np.empty(1, dtype=np.longlong)
        c0 = time.thread_time()
        _cgco.gcoExpansion(h, np.intc(-1), energy)
        cpu_ms = (time.thread_time() - c0) * 1e3
    finally:
        _cgco.gcoDestroyGraph(h)
    return int(energy[0]), cpu_ms


def motif_solve(motif, path, threads, fresh=False):
    with tempfile.NamedTemporaryFile(suffix=".json") as out:
        subprocess.run([motif, "mrf", "solve", path, "--threads", str(threads), "--quiet", "--force",
                        "--json", out.name] + (["--no-recycle"] if fresh else []), check=True,
                       stdout=subprocess.DEVNULL)
        report = json.load(open(out.name))
    return int(round(report["energy"])), report["solve_ms"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--motif", required=True, help="the motif binary")
    ap.add_argument("--rounds", type=int, default=3, help="interleaved runs per solver (medians)")
    ap.add_argument("--large", action="store_true", help="also the 30^3 grids (minutes)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    sizes = [((10, 10, 10), 8), ((20, 20, 20), 30)] + ([((30, 30, 30), 64)] if args.large else [])
    threads = os.cpu_count() or 1
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for dims, labels in sizes:
            for conn in (6, 26):
                name = f"{dims[0]}^3, {labels} labels, {conn}-conn."
                path = os.path.join(tmp, f"grid_{dims[0]}_{labels}_{conn}.json")
                subprocess.run([args.motif, "mrf", "generate", "--dims", ",".join(map(str, dims)),
                                "--labels", str(labels), "--connectivity", str(conn), "--seed",
                                str(args.seed), "-o", path, "--quiet"], check=True)
                problem = json.load(open(path))
                times = {"gco": [], "motif1": [], "motifN": [], "fresh1": []}
                energies = {}
                for r in range(args.rounds):
                    print(f"{name}: round {r + 1}/{args.rounds}", file=sys.stderr)
                    energies["gco"], t = gco_solve(problem)
                    times["gco"].append(t)
                    energies["motif1"], t = motif_solve(args.motif, path, 1)
                    times["motif1"].append(t)
                    energies["motifN"], t = motif_solve(args.motif, path, threads)
                    times["motifN"].append(t)
                    energies["fresh1"], t = motif_solve(args.motif, path, 1, fresh=True)
                    times["fresh1"].append(t)
                med = {k: statistics.median(v) for k, v in times.items()}
                rows.append((name, energies, med))
    print(f"Alpha-expansion on mrf_grid_v1 problems (seed {args.seed}), medians of {args.rounds} "
          f"interleaved runs")
    print(f"{'problem':28} {'GCO energy':>12} {'Motif energy':>12} {'GCO ms':>10} "
          f"{'Motif 1 thr':>12} {'ratio':>6} {f'Motif {threads} thr':>12} {'ratio':>6} "
          f"{'fresh 1 thr':>12} {'ratio':>6}")
    for name, e, m in rows:
        same = "" if e["motif1"] == e["gco"] == e["motifN"] == e["fresh1"] else "  (energies differ)"
        print(f"{name:28} {e['gco']:>12} {e['motif1']:>12} {m['gco']:>10.1f} {m['motif1']:>12.1f} "
              f"{m['motif1'] / m['gco']:>6.2f} {m['motifN']:>12.1f} {m['motifN'] / m['gco']:>6.2f} "
              f"{m['fresh1']:>12.1f} {m['fresh1'] / m['gco']:>6.2f}{same}")
    print("fresh: Motif with --no-recycle (every move's graph built anew, as GCO does)")


if __name__ == "__main__":
    main()
