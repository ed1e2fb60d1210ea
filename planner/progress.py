"""Progress of long commands: bars on a terminal (stderr), one line per stage elsewhere (stdout).

The library reports progress through a callback ``progress(stage, done, total)``; the command
line turns it into what the user sees:

* on a terminal (stderr is a TTY), one tqdm bar per stage, removed when the stage ends;
* otherwise (a pipe, a log file, a CI job), one line per stage on **stdout** when it starts,
  ``compplan: [  12.3 s] <stage> (<total> <unit>)``, the time since the command started, so a
  log shows what a long run is doing and where its time went.  On stdout, with the command's
  other lines, so that stderr holds only warnings and the one line of an error.
"""

from __future__ import annotations

import contextlib
import sys
import time
from typing import Any, TextIO
from collections.abc import Callable, Iterator

from models import interrupts

#: Progress units of the stages that do not count figures: (unit, scale to k/M).
UNITS = {
    "compliance map": ("pt", True),
    "placement sweep": ("pose", True),
    "full plans": ("plan", False),
    "posture": ("stage", False),
    "compensation": ("stage", False),
    "identify": ("step", False),
}

#: When the command started (:func:`start_clock`, called by the command line first thing).
_START = [time.monotonic()]


def start_clock() -> None:
    """Stage lines count the seconds from now (the command's start)."""
    _START[0] = time.monotonic()


def unit_of(stage: str) -> tuple[str, bool]:
    """The unit of a stage's count and whether tqdm scales it to k/M."""
    return UNITS.get(stage, ("stretch", False) if stage.startswith("timing ") else ("fig", False))


def on_terminal(stream: TextIO | None = None) -> bool:
    """Whether ``stream`` (default stderr) is a terminal: bars there, stage lines elsewhere."""
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # closed or not a file
        return False


class StageLines:
    """One line per stage on a stream that is not a terminal (a log, a pipe): ``stream``, default stdout.

    ``key`` maps a stage's words to the stage it belongs to (default: the words themselves): the
    first words of a stage are printed, the others are not."""

    def __init__(self, stream: TextIO | None = None, key: Callable[[str], str] | None = None) -> None:
        self.stream = stream
        self.key = key
        self._seen: set[str] = set()

    def __call__(self, stage: str, done: int, total: int, unit: str = "") -> None:
        k = stage if self.key is None else self.key(stage)
        if k in self._seen:
            return
        self._seen.add(k)
        stream = sys.stdout if self.stream is None else self.stream
        sys.stderr.flush()  # a warning printed before this stage comes first in a shared log
        count = f" ({total} {unit})" if unit and total > 1 else ""
        print(f"compplan: [{time.monotonic() - _START[0]:7.1f} s] {stage}{count}", file=stream, flush=True)


class TqdmProgress:
    """``progress(stage, done, total)`` callback: one tqdm bar per stage on a terminal, one line
    per stage elsewhere (:class:`StageLines`)."""

    def __init__(self) -> None:
        self._bars: dict[str, Any] = {}
        self._lines = None if on_terminal() else StageLines()

    def __call__(self, stage: str, done: int, total: int) -> None:
        interrupts.raise_if_pending()  # a signal lost in a destructor: stop at the next tick
        unit, scale = unit_of(stage)
        if self._lines is not None:
            self._lines(stage, done, total, unit)
            return
        from tqdm import tqdm

        bar = self._bars.get(stage)
        if bar is None:
            bar = tqdm(total=total, desc=stage, unit=unit, unit_scale=scale, file=sys.stderr, leave=False)
            self._bars[stage] = bar
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    def close(self) -> None:
        for bar in self._bars.values():
            bar.close()
        self._bars.clear()


@contextlib.contextmanager
def report_progress() -> Iterator[TqdmProgress]:
    """A :class:`TqdmProgress` whose bars are closed on exit (also on error)."""
    p = TqdmProgress()
    try:
        yield p
    finally:
        p.close()
