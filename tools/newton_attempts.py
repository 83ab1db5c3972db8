#!/usr/bin/env python3
"""Newton attempts of traced runs, and what a rule ending stagnating attempts early would do.

Usage:
    tools/newton_attempts.py TRACE...

Each TRACE is the standard error of `FRICSENS_TRACE=1 fricsens run SCENE --no-vtk`, named
SEED.log (for example, for seeds 0-999 of the physics fuzzer:
`fricsens fuzz --show S > S.toml; FRICSENS_TRACE=1 fricsens run S.toml --no-vtk 2> S.log`).

An attempt is a run of the trace's iteration lines (`t = ... k = K ... r = R`) from k = 0 to
the next k = 0 (a new attempt, increment or augmented-Lagrangian pass); it failed when an
"attempt failed", "Newton failed" or "augmentation: the pass failed" line follows it (an
"attempt failed" line whose residual list is empty is an attempt that failed before its first
evaluation). Of an iteration repeated by the line search the last residual counts, and an
attempt's iterations are its Newton steps (its largest k; the trace does not show the
active-set predictor's settling solves). Prints the iterations in failed attempts per seed
(the ten seeds with the most) and, for the rule "end the attempt at the first iteration
k >= K0 whose last M residuals are all above c times the best before them", the iterations
it would save in failed attempts and the converging attempts (and scenes) it would end.
"""
import collections
import os
import re
import sys

LINE = re.compile(r"^  t = (\S+) k = (\d+) alpha = \S+ r = (\S+)")
FAILED = ("attempt failed", "Newton failed", "augmentation: the pass failed")


def attempts(path):
    """(residuals per iteration from k = 0, failed) of every attempt in one trace."""
    out, cur = [], None
    for line in open(path, errors="replace"):
        m = LINE.match(line)
        if m:
            k, r = int(m.group(2)), float(m.group(3))
            if k == 0:
                if cur is not None:
                    out.append((cur, False))
                cur = {0: r}
            elif cur is not None:
                cur[k] = r
        elif "attempt failed" in line and "residuals []" in line:
            # failed before its first evaluation: whatever came before converged
            if cur is not None:
                out.append((cur, False))
            out.append(({}, True))
            cur = None
        elif any(w in line for w in FAILED) and cur is not None:
            out.append((cur, True))
            cur = None
    if cur is not None:
        out.append((cur, False))
    return [([d[k] for k in sorted(d)], failed) for d, failed in out]


def fires(r, k0, m, c):
    """The iteration at which the rule ends the attempt of residuals `r`, or None."""
    for k in range(max(k0, m), len(r)):
        if min(r[k - m + 1 : k + 1]) > c * min(r[: k - m + 1]):
            return k
    return None


def steps(r):
    """Newton steps of an attempt of residuals `r` (one per iteration from k = 0)."""
    return max(len(r) - 1, 0)


def main(paths):
    segs = []
    for p in paths:
        seed = os.path.basename(p).split(".")[0]
        segs += [(seed, r, f) for r, f in attempts(p)]
    total = sum(steps(r) for _, r, _ in segs)
    failed = sum(steps(r) for _, r, f in segs if f)
    print(f"{len(segs)} attempts, {sum(f for *_, f in segs)} failed; "
          f"{total} Newton iterations, {failed} in failed attempts")
    per, wasted = collections.Counter(), collections.Counter()
    for s, r, f in segs:
        per[s] += steps(r)
        if f:
            wasted[s] += steps(r)
    for s, w in wasted.most_common(10):
        print(f"  seed {s}: {w} of {per[s]} iterations in failed attempts ({100 * w / per[s]:.0f} %)")
    print("K0 M c: iterations saved in failed attempts, converging attempts ended (scenes)")
    for k0 in (6, 8, 10):
        for m in (4, 6, 8):
            for c in (1.0, 0.5):
                saved, ended = 0, []
                for s, r, f in segs:
                    k = fires(r, k0, m, c)
                    if k is None:
                        continue
                    if f:
                        saved += steps(r) - k
                    elif k < len(r) - 1:
                        ended.append(s)
                print(f"{k0} {m} {c}: {saved}, {len(ended)} ({len(set(ended))})")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
