#!/usr/bin/env python3
"""Newton attempts of traced runs, and what a rule ending stagnating attempts early would do.

Usage:
    tools/newton_attempts.py TRACE...

Each TRACE is the standard error of `FRICSENS_TRACE=1 fricsens run SCENE --no-vtk`, named
SEED.log (for example, for seeds 0-999 of the physics fuzzer:
`fricsens fuzz --show S > S.toml; FRICSENS_TRACE=1 fricsens run S.toml --no-vtk 2> S.log`).

An attempt is a run of the trace's iteration lines (`t = ... k = K ... r = R`) from k = 0 to
the next k = 0 (a new attempt, increment or augmented-Lagrangian pass); it failed when an
"attempt failed" or "Newton failed" line follows it. Of an iteration repeated by the line
search the last residual counts. Prints the iterations in failed attempts per seed (the ten
seeds with the most) and, for the rule "end the attempt at the first iteration k >= K0
whose last M residuals are all above c times the best before them", the iterations it would
save in failed attempts and the converging attempts (and scenes) it would end.
"""
import collections
import os
import re
import sys

LINE = re.compile(r"^  t = (\S+) k = (\d+) alpha = \S+ r = (\S+)")


def attempts(path):
    """(residuals per iteration, failed) of every attempt in one trace."""
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
        elif ("attempt failed" in line or "Newton failed" in line) and cur is not None:
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


def main(paths):
    segs = []
    for p in paths:
        seed = os.path.basename(p).split(".")[0]
        segs += [(seed, r, f) for r, f in attempts(p)]
    total = sum(len(r) for _, r, _ in segs)
    failed = sum(len(r) for _, r, f in segs if f)
    print(f"{len(segs)} attempts, {sum(f for *_, f in segs)} failed; "
          f"{total} iterations, {failed} in failed attempts")
    per, wasted = collections.Counter(), collections.Counter()
    for s, r, f in segs:
        per[s] += len(r)
        if f:
            wasted[s] += len(r)
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
                        saved += len(r) - 1 - k
                    elif k < len(r) - 1:
                        ended.append(s)
                print(f"{k0} {m} {c}: {saved}, {len(ended)} ({len(set(ended))})")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
