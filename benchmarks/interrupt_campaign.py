"""Interrupts at many random moments of every long command (issue 34): a campaign, not a test.

Runs each long command of ``tests/test_interrupt_moments.py`` (its :data:`CASES`) once in full,
then ``--moments`` times stopped at a random moment in (0.2 s, 0.95 T): SIGINT to the process
group (Ctrl-C at a terminal) and SIGTERM to the process (``kill``) in turn.  Each stopped run is
checked by the test module's :func:`defects` (exit 130 within the latency bound, one last line
``compplan: interrupted``/``terminated``, no traceback, the previous output intact, no hidden
sibling, no process left); a run that had already finished must have written its outputs whole.
Prints one row per command::

    command        n  finished  handled  max latency (s)  seed

and the defects of every run that was not handled, with its moment.  Exits 1 if one was not.
The seed is ``--seed`` (default: a fresh one, printed).  Usage::

    python benchmarks/interrupt_campaign.py [--moments 20] [--seed N] [--only plan,demo] [--keep DIR]
"""

from __future__ import annotations

import argparse
import random
import signal
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.test_interrupt_moments import (  # after the path above
    CASES,
    INTERRUPT_LATENCY_S,
    defects,
    moments,
    prepare_inputs,
    run,
    run_full,
    tree,
)


def campaign(folder: Path, n: int, seed: int, only: set[str] | None) -> bool:
    """Run the campaign in ``folder``; print the table; whether every stopped run was handled."""
    prepare_inputs(folder)
    print(f"seed {seed}; latency bound {INTERRUPT_LATENCY_S} s")
    print(f"{'command':<14}{'n':>4}{'finished':>10}{'handled':>9}{'max latency (s)':>17}{'full run (s)':>14}")
    failures: list[str] = []
    for index, case in enumerate(CASES):
        if only and case.name not in only:
            continue
        full, outputs = run_full(case, folder)
        handled = finished = 0
        latencies: list[float] = []
        for k, at_s in enumerate(moments(seed + index, full.duration_s, n)):
            sig = signal.SIGINT if k % 2 == 0 else signal.SIGTERM
            before = {o: tree(folder / o) for o in case.outputs}
            outcome = run(case, folder, sig, at_s, group=sig == signal.SIGINT)
            found = defects(case, folder, sig, outcome, before, outputs)
            if outcome.latency_s is not None:
                latencies.append(outcome.latency_s)
            finished += outcome.code == 0
            handled += not found
            if found:
                tail = " | ".join(outcome.stderr.strip().splitlines()[-4:])
                failures.append(
                    f"{case.name} {signal.Signals(sig).name} at {at_s:.2f} s: {'; '.join(found)}\n    {tail}"
                )
            if outcome.code == 0:
                outputs = {o: tree(folder / o) for o in case.outputs}
        worst = f"{max(latencies):.2f}" if latencies else "-"
        print(f"{case.name:<14}{n:>4}{finished:>10}{handled:>9}{worst:>17}{full.duration_s:>14.1f}", flush=True)
    for line in failures:
        print(line)
    return not failures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--moments", type=int, default=20, help="stopped runs per command")
    parser.add_argument("--seed", type=int, default=None, help="seed of the moments (default: fresh)")
    parser.add_argument("--only", default="", help="comma-separated case names (default: all)")
    parser.add_argument("--keep", type=Path, default=None, help="work in this folder and keep it")
    args = parser.parse_args()
    seed = random.SystemRandom().randrange(1 << 31) if args.seed is None else args.seed
    only = {x for x in args.only.split(",") if x} or None
    if args.keep is not None:
        return 0 if campaign(args.keep, args.moments, seed, only) else 1
    with tempfile.TemporaryDirectory(prefix="interrupt-campaign-") as folder:
        return 0 if campaign(Path(folder), args.moments, seed, only) else 1


if __name__ == "__main__":
    sys.exit(main())
