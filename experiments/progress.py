"""Progress of long jobs: a tqdm bar with ETA on a terminal, a periodic one-line status otherwise.

Campaigns, training runs, reproductions, GA tuning and benchmarks report through
:class:`Progress`. On a terminal (the stream's ``isatty()``) it is a :mod:`tqdm` bar; in a log
file or a pipe it writes one line every ``ATTITUDE_ENVS_PROGRESS_S`` seconds (default 30) and a
last one when the job ends, e.g. ``campaign episodes: 120/400 (30 %), 1:02 elapsed, ETA 2:25``.
Output goes to stderr, so results on stdout stay clean.
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
from typing import TextIO

from tqdm import tqdm

INTERVAL_ENV = "ATTITUDE_ENVS_PROGRESS_S"
DEFAULT_INTERVAL_S = 30.0


def status_interval_s() -> float:
    """Seconds between status lines when not on a terminal (``ATTITUDE_ENVS_PROGRESS_S``, default 30)."""
    text = os.environ.get(INTERVAL_ENV)
    if not text:
        return DEFAULT_INTERVAL_S
    try:
        value = float(text)
    except ValueError as exc:
        raise ValueError(f"{INTERVAL_ENV} must be a number of seconds >= 0, got {text!r}") from exc
    if not value >= 0.0:
        raise ValueError(f"{INTERVAL_ENV} must be a number of seconds >= 0, got {text!r}")
    return value


def format_duration(seconds: float) -> str:
    """``1:02`` (m:ss) or ``2:01:02`` (h:mm:ss); ``?`` when unknown."""
    if not math.isfinite(seconds) or seconds < 0:
        return "?"
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class _Bar(tqdm):
    """tqdm whose rate (and so ETA) is measured from the first item done on (``origin``, set by
    :class:`Progress`): none before it, as the status lines. tqdm's own rate would take the
    start-up into its first estimate (110 campaign episodes, the first after 35 s of workers
    starting and compiling: ETA 1:05, for a minute of work)."""

    origin: tuple[float, int] | None = None

    def mark_origin(self, n: int) -> None:
        """``n`` items are done now: the rate is measured from here on."""
        self.origin = (self._time(), int(n))

    @property
    def format_dict(self):
        d = super().format_dict
        now = self._time()
        if self.origin is None or self.n <= self.origin[1] or now <= self.origin[0]:
            d["rate"] = 0  # tqdm prints '?' for the rate and the time left
        else:
            d["rate"] = (self.n - self.origin[1]) / (now - self.origin[0])
        return d


class Progress:
    """Progress over ``total`` items (``n`` starts at ``initial``, e.g. a resumed run's steps).

    ``bar``: True a tqdm bar, False status lines, None (default) a bar exactly when ``stream``
    (default stderr) is a terminal. ``enabled=False`` makes every call a no-op. Use as a
    context manager, or call :meth:`close`.
    """

    def __init__(
        self,
        total: int,
        desc: str,
        unit: str = "it",
        *,
        initial: int = 0,
        enabled: bool = True,
        bar: bool | None = None,
        stream: TextIO | None = None,
        interval_s: float | None = None,
    ) -> None:
        self.total = int(total)
        self.desc = desc
        self.unit = unit
        self.initial = self.n = int(initial)
        self.enabled = bool(enabled)
        self.stream = stream if stream is not None else sys.stderr
        self.interval_s = status_interval_s() if interval_s is None else float(interval_s)
        self.start = self.last = time.monotonic()
        self.first: tuple[float, int] | None = None  # (time, count) of the first progress: the ETA's origin
        self.lines = 0
        self.postfix = ""
        self._closed = False
        use_bar = self.stream.isatty() if bar is None else bool(bar)
        self._bar = None
        if self.enabled and use_bar:
            self._bar = _Bar(
                total=self.total, initial=self.n, desc=desc, unit=unit, file=self.stream, dynamic_ncols=True
            )

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def set_postfix(self, text: str) -> None:
        """A short note shown after the counts (e.g. ``best 12.3``)."""
        if not self.enabled or self._closed:
            return
        self.postfix = str(text)
        if self._bar is not None:
            self._bar.set_postfix_str(self.postfix, refresh=False)

    def update(self, n: int = 1) -> None:
        """``n`` more items done."""
        self.update_to(self.n + int(n))

    def update_to(self, n: int) -> None:
        """``n`` items done in all."""
        if not self.enabled or self._closed:
            return
        n = int(n)
        if self._bar is not None:
            if self._bar.origin is None and n > self.initial:
                self._bar.mark_origin(n)
            self._bar.update(n - self.n)
        self.n = n
        now = time.monotonic()
        if self.first is None and n > self.initial:
            self.first = (now, n)
        if self._bar is None and now - self.last >= self.interval_s and self.n < self.total:
            self._line(now)

    def status(self, now: float | None = None) -> str:
        """The one-line status: done/total, percent, elapsed, ETA. The ETA is ``?`` until the
        first item is done and progress has been made since: its rate is measured from the first
        item done on, so a start-up (workers starting, a JIT compilation, a first job much longer
        than the rest) does not stretch it (a first ETA of an hour for three minutes of work)."""
        now = time.monotonic() if now is None else now
        elapsed = now - self.start
        rate = 0.0
        if self.first is not None and self.n > self.first[1] and now > self.first[0]:
            rate = (self.n - self.first[1]) / (now - self.first[0])
        eta = (self.total - self.n) / rate if rate > 0 else float("nan")
        pct = 100.0 * self.n / self.total if self.total else 100.0
        unit = f" {self.unit}" if self.unit != "it" and self.unit not in self.desc else ""
        note = f", {self.postfix}" if self.postfix else ""
        return (
            f"{self.desc}: {self.n}/{self.total}{unit} ({pct:.0f} %), "
            f"{format_duration(elapsed)} elapsed, ETA {format_duration(eta)}{note}"
        )

    def _line(self, now: float) -> None:
        self.last = now
        self.lines += 1
        print(self.status(now), file=self.stream, flush=True)

    def close(self) -> None:
        """End the bar, or write the last status line (only if a line was written before, or the
        job took longer than one interval)."""
        if not self.enabled or self._closed:
            return
        self._closed = True
        if self._bar is not None:
            self._bar.close()
            return
        now = time.monotonic()
        if self.lines or now - self.start >= self.interval_s:
            elapsed = format_duration(now - self.start)
            note = f", {self.postfix}" if self.postfix else ""
            print(f"{self.desc}: {self.n}/{self.total} done in {elapsed}{note}", file=self.stream, flush=True)


class Heartbeat:
    """Progress of a job whose size is not known in advance (e.g. a paper reproduction): the
    elapsed time, beside ``typical_s`` (a typical duration) when given. On a terminal a tqdm
    counter refreshed every second; otherwise one line every ``ATTITUDE_ENVS_PROGRESS_S``
    seconds. A daemon thread writes it; use as a context manager."""

    def __init__(
        self,
        desc: str,
        typical_s: float | None = None,
        *,
        bar: bool | None = None,
        stream: TextIO | None = None,
        interval_s: float | None = None,
    ) -> None:
        self.desc = desc
        self.typical_s = typical_s
        self.stream = stream if stream is not None else sys.stderr
        self.interval_s = status_interval_s() if interval_s is None else float(interval_s)
        self.use_bar = self.stream.isatty() if bar is None else bool(bar)
        self.lines = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True, name="progress-heartbeat")
        self.start = time.monotonic()

    def __enter__(self) -> Heartbeat:
        self.start = time.monotonic()
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()

    def status(self) -> str:
        typical = f" (typically {format_duration(self.typical_s)})" if self.typical_s else ""
        return f"{self.desc}: {format_duration(time.monotonic() - self.start)} elapsed{typical}"

    def _run(self) -> None:
        if self.use_bar:
            typical = f" (typically {format_duration(self.typical_s)})" if self.typical_s else ""
            fmt = "{desc}: {elapsed} elapsed" + typical
            with tqdm(total=None, desc=self.desc, file=self.stream, bar_format=fmt) as bar:
                while not self._stop.wait(1.0):
                    bar.refresh()
            return
        while not self._stop.wait(max(self.interval_s, 0.05)):
            self.lines += 1
            print(self.status(), file=self.stream, flush=True)
