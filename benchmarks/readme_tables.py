"""Print the README's result tables (Markdown) from `gromov reproduce` results files.

    .venv/bin/python benchmarks/readme_tables.py [RESULTS.json ...]

Without arguments: the three committed runs (paper's classes + TOPKIDS, held-out classes,
synthetic set). Every number is read from the file; the paper's are
:data:`gromov.experiments.report.PAPER`. Nothing is computed again.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from gromov.experiments.report import PAPER, errors_text, other_classes

HERE = Path(__file__).resolve().parent / "results"
DEFAULT = [HERE / "reproduce-tosca" / "results.json", HERE / "reproduce-heldout" / "results.json",
           HERE / "synthetic" / "results.json"]
METRICS = ("geodesic", "diffusion")
EXPERIMENTS = (("weld", "Experiment 1 (welds)"), ("holes", "Experiment 2 (holes)"))
# the paper reports one correspondence number "with topology changes"; compared with both
# welds and holes, as the report does
PAPER_CONDITION = {"clean": "clean", "weld": "topology", "holes": "topology"}


def _pct(x) -> str:
    if x is None:
        return "–"
    return f"{100 * x:.1f}%" if 100 * x >= 10 or x == 0 else f"{100 * x:.2f}%"


def _num(x, digits: int = 3) -> str:
    return "–" if x is None else f"{x:.{digits}f}"


def _paper(*keys):
    d = PAPER
    for k in keys:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def table(r: dict) -> str:
    """One Markdown table: rows of measures, columns geodesic / diffusion (ours, paper)."""
    rec, cor = r["recognition"], r["correspondence"]
    # the paper's columns only beside the paper's classes
    paper_cols = r.get("dataset") == "tosca" and not other_classes(r)
    head = "| | geodesic | diffusion |" + (" geodesic (paper) | diffusion (paper) |" if paper_cols else "")
    rule = "|---|---:|---:|" + ("---:|---:|" if paper_cols else "")
    rows = [head, rule]

    def row(label, ours, paper=None):
        cells = [label, *ours] + ([*(paper or ("–", "–"))] if paper_cols else [])
        rows.append("| " + " | ".join(cells) + " |")

    for exp, name in EXPERIMENTS:
        if exp not in rec:
            continue
        row(f"EER, {name}", [_pct(rec[exp][m]["eer"]) for m in METRICS],
            [_pct(_paper("eer", exp, m)) for m in METRICS])
    for exp, name in EXPERIMENTS:
        if exp in rec:
            row(f"EER by the GH estimate, {name}", [_pct(rec[exp][m]["eer_gh"]) for m in METRICS])
    for exp, name in EXPERIMENTS:   # a set-level normalisation: never beside the paper's numbers
        if exp in rec and "eer_local" in rec[exp]["diffusion"]:
            k = rec[exp]["diffusion"]["local_scaling_k"]
            row(f"EER after local scaling (k = {k}), {name}", [_pct(rec[exp][m]["eer_local"]) for m in METRICS])
    nn = [" / ".join(_pct(rec[e][m]["nn_accuracy"]) for e, _ in EXPERIMENTS if e in rec)
          for m in METRICS]
    row("nearest-neighbour accuracy, Exp. 1 / Exp. 2", nn)
    for cond in ("clean", "weld", "holes"):
        if cond not in cor["diffusion"]:
            continue
        ours = [f"{_num(cor[m][cond])} ({_num(cor[m].get(cond + '_direct'))})" for m in METRICS]
        row(f"d(C, C0) {'welds' if cond == 'weld' else cond}, best (direct)", ours,
            [_num(_paper("correspondence", m, PAPER_CONDITION[cond]), 4) for m in METRICS])
    t = r.get("topkids")
    if t:
        row("TOPKIDS d(C, C0), best (direct)",
            [f"{_num(t[m]['correspondence'])} ({_num(t[m]['correspondence_direct'])})" for m in METRICS])
        row("TOPKIDS GH ÷ diameter to kid00, mean; Spearman ρ with the handles",
            [f"{_num(t[m]['relative_distance_mean'])}; {_num(t[m]['spearman_distance_vs_handles'], 2)}"
             for m in METRICS])
    return "\n".join(rows)


def errors(r: dict) -> str:
    """Where the diffusion errors are at its EER threshold, per experiment (as the report says)."""
    out = []
    for exp, name in EXPERIMENTS:
        e = r["recognition"].get(exp, {}).get("diffusion", {}).get("errors_at_eer")
        if e:
            out.append(f"- {name}, diffusion, at its EER threshold: {errors_text(e)}.")
    return "\n".join(out)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("files", nargs="*", type=Path, default=DEFAULT)
    a = p.parse_args(argv)
    for f in a.files:
        r = json.loads(f.read_text())
        print(f"### {f}  ({r.get('date', '?')}, {r.get('seconds_total', '?')} s)")
        print(f"`{r.get('command', '?')}`\n")
        print(table(r))
        print()
        print(errors(r))
        print()


if __name__ == "__main__":
    main()
