#!/usr/bin/env python3
"""The adjoint's cost targets for one response (the project's issue 28: at most 10 % of the
primal and 1.5 times one DDM parameter), measured in rounds taken in turns.

A first adjoint run, not timed, reads the study's parameter names. Each round then runs,
one after the other with the same binary: the adjoint with every parameter
of the scene's study, then DDM with each of those parameters alone, then DDM with all of them,
every run with the same response and tangent. Each run's own ledger gives its primal and its
sensitivity time (`cost: primal X s; sensitivity Y s`), so every ratio below is of two runs of
one round, taken minutes apart at most; the machine's load moves them by tens of per cent from
round to round, so the medians and quartiles over the rounds are what to read.

Printed per round and as medians (quartiles):
  adjoint / primal                the adjoint's sweep over the primal of its own run
  adjoint / DDM(P)                against a DDM run with parameter P alone ("one DDM parameter")
  adjoint / (DDM(all) / n)        against DDM's mean cost per parameter when it batches all n
  adjoint / (DDM(all) - DDM(P))   against what the other parameters add to P's DDM run: with
                                  two, the marginal cost of the other in a batch (the strictest)

Both methods give the one-sided derivatives at the flagged increments they read (the
adjoint: two more columns per response at each); `--no-one-sided` leaves them out of both.

usage: tools/adjoint_targets.py [--bin target/release/fricsens] [--scene leaf-spring]
           [--tangent last] [--response block-force] [--rounds 20] [--no-one-sided]
"""
import argparse
import re
import statistics
import subprocess
import tempfile

COST = re.compile(r"cost: primal ([0-9.eE+-]+) s; sensitivity ([0-9.eE+-]+) s")


def run(binary, scene, out, args):
    """One `fricsens sensitivity` run: (primal seconds, sensitivity seconds, parameters)."""
    p = subprocess.run(
        [binary, "sensitivity", scene, "--out", out, *args],
        capture_output=True,
        text=True,
        check=True,
    )
    text = p.stdout + p.stderr
    m = COST.search(text)
    if not m:
        raise SystemExit(f"no cost line in the output of {' '.join(args)}:\n{text}")
    # the names are quoted, and a field parameter's has brackets of its own (`upper.E[3]`)
    params = re.search(r'parameters \[((?:"[^"]*"(?:, )?)*)\]', text)
    names = re.findall(r'"([^"]+)"', params.group(1)) if params else []
    return float(m.group(1)), float(m.group(2)), names


def quartiles(v):
    q1, med, q3 = statistics.quantiles(v, n=4, method="inclusive")
    return med, q1, q3


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", default="target/release/fricsens")
    ap.add_argument("--scene", default="leaf-spring")
    ap.add_argument("--tangent", default="last")
    ap.add_argument("--response", default="block-force")
    ap.add_argument("--rounds", type=int, default=20)
    ap.add_argument("--no-one-sided", action="store_true")
    a = ap.parse_args()
    common = ["--tangent", a.tangent, "--response", a.response]
    if a.no_one_sided:
        common.append("--no-one-sided")
    with tempfile.TemporaryDirectory() as out:
        _, _, params = run(a.bin, a.scene, out, ["--method", "adjoint", *common])
        if not params:
            raise SystemExit("the adjoint's output names no parameters")
        rows = []
        for r in range(a.rounds):
            primal, adj, _ = run(a.bin, a.scene, out, ["--method", "adjoint", *common])
            one = {
                p: run(a.bin, a.scene, out, ["--method", "ddm", "--param", p, *common])[1]
                for p in params
            }
            batch = run(a.bin, a.scene, out, ["--method", "ddm", *common])[1]
            row = {"adjoint / primal": adj / primal}
            for p in params:
                row[f"adjoint / DDM({p})"] = adj / one[p]
            row[f"adjoint / (DDM(all) / {len(params)})"] = adj / (batch / len(params))
            # with one parameter there is no other to add; a batch timed at or under the
            # run of one of its parameters (the machine's noise) gives no ratio
            for p in params if len(params) > 1 else []:
                extra = batch - one[p]
                row[f"adjoint / (DDM(all) - DDM({p}))"] = adj / extra if extra > 0 else float("inf")
            rows.append(row)
            cells = " ".join(f"{v:.3f}" for v in row.values())
            print(f"round {r + 1}: adjoint {adj:.3f} s, primal {primal:.3f} s, "
                  f"DDM {' '.join(f'{p} {t:.3f} s' for p, t in one.items())}, "
                  f"all {batch:.3f} s; ratios {cells}", flush=True)
    sided = ", --no-one-sided" if a.no_one_sided else ""
    print(f"\n{a.scene}, --tangent {a.tangent}, --response {a.response}{sided}, "
          f"{a.rounds} rounds, parameters {params}:")
    for k in rows[0]:
        med, q1, q3 = quartiles([row[k] for row in rows])
        under = sum(row[k] <= 1.5 for row in rows) if k != "adjoint / primal" else None
        tail = f", {under} of {len(rows)} rounds <= 1.5" if under is not None else ""
        print(f"  {k:42s} median {med:.3f} (quartiles {q1:.3f}, {q3:.3f}){tail}")


if __name__ == "__main__":
    main()
