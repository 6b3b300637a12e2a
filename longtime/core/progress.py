"""What a long command is doing and how far it is, on stderr, from start to end.

A command opens a ``Progress`` (off with --no-progress or --quiet) and runs each of its
phases inside ``progress.phase(name, total=..., estimate_s=...)``, calling ``advance`` as a
unit of work ends. Where stderr is a terminal that reports its width, each phase is a tqdm
bar (count, rate, time left where there is a total; else the time spent and the expected
time), redrawn every ``TERMINAL_SECONDS`` even when no unit ends. Elsewhere (a pipe, a CI
log, ``| tee``, a terminal that reports 0 columns) each phase is plain lines, one line per
message, newline-terminated: one when the phase starts, one every ``PLAIN_SECONDS``, one
when it ends. ``$LONGTIME_PROGRESS_SECONDS`` sets both intervals.

A phase of units of unequal cost (the cells of a matrix) can be given each unit's estimated
cost (``costs``, ``advance(cost=...)``): its time left is then the time spent times the
estimated cost left over the estimated cost done, not over the units done.

A single run of a scheme that goes on for more than ``RUN_SECONDS`` prints a ``RunProgress``
line on stderr every ``RUN_SECONDS`` (``$LONGTIME_PROGRESS=0`` turns these lines off).
"""
from __future__ import annotations

import contextlib
import os
import sys
import threading
import time
from typing import Any, Iterator, TextIO

ENV_SECONDS = "LONGTIME_PROGRESS_SECONDS"
TERMINAL_SECONDS = 5.0  # a redraw of the bar: a terminal sees something at least this often
PLAIN_SECONDS = 30.0  # a line in a log: at least this often
RUN_SECONDS = 10.0  # a run still going after this many wall seconds says where it is, this often


def is_terminal(stream: Any) -> bool:
    """Whether ``stream`` is a terminal that reports a width (a pseudo-terminal that reports
    0 columns draws no bar)."""
    try:
        return bool(stream.isatty()) and os.get_terminal_size(stream.fileno()).columns > 0
    except (AttributeError, OSError, ValueError):
        return False


def interval(terminal: bool) -> float:
    """Seconds between two updates: $LONGTIME_PROGRESS_SECONDS where set (> 0), else
    TERMINAL_SECONDS in a terminal and PLAIN_SECONDS elsewhere."""
    try:
        given = float(os.environ.get(ENV_SECONDS, ""))
    except ValueError:
        given = 0.0
    return given if given > 0 else (TERMINAL_SECONDS if terminal else PLAIN_SECONDS)


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 60}:{seconds % 60:02d}" if seconds >= 60 else f"{seconds} s"


class Progress:
    """The progress of one command's phases on ``stream`` (stderr); ``on=False`` prints nothing."""

    def __init__(self, on: bool = True, stream: TextIO | None = None) -> None:
        self.on = on
        self.stream = stream if stream is not None else sys.stderr
        self.terminal = on and is_terminal(self.stream)
        self.every = interval(self.terminal)
        self._lock = threading.Lock()
        self._state: dict[str, Any] | None = None
        self._bar: Any = None

    def say(self, text: str) -> None:
        """One line (outside any bar)."""
        if not self.on:
            return
        with self._lock:
            if self._bar is not None:
                self._bar.write(f"longtime: {text}", file=self.stream)
            else:
                print(f"longtime: {text}", file=self.stream, flush=True)

    @contextlib.contextmanager
    def phase(self, name: str, total: int | None = None, unit: str = "", estimate_s: float | None = None,
              detail: str = "", announce: bool = True, costs: float | None = None) -> Iterator["Progress"]:
        """The ``with`` block as phase ``name``: ``total`` units of ``unit`` (``advance`` counts
        them), or an expected duration ``estimate_s``; ``detail`` says what it works on.
        ``costs``: the units' estimated costs together (in any unit; ``advance(cost=...)``
        gives each finished unit's), from which the time left is estimated.
        ``announce=False``: silent unless the phase outlasts one interval (a command that is
        usually quick, whose stderr says nothing else then)."""
        if not self.on:
            yield self
            return
        state = {"name": name, "total": total, "unit": unit, "done": 0, "start": time.monotonic(),
                 "estimate": estimate_s, "detail": detail, "last": "", "spoke": announce,
                 "costs": costs if costs and costs > 0 else None, "cost_done": 0.0}
        outer, outer_bar = self._state, self._bar
        self._state, self._bar = state, None
        if announce and self.terminal:
            self._bar = self._new_bar(state)
        elif announce:
            self._line(state, "started")
        stop = threading.Event()
        beat = threading.Thread(target=self._beat, args=(state, stop), daemon=True, name=f"progress {name}")
        beat.start()
        failed = False
        try:
            yield self
        except BaseException:
            failed = True  # the error says what happened: no "done" line
            raise
        finally:
            stop.set()
            beat.join()
            with self._lock:
                if self._bar is not None and self._bar is not outer_bar:
                    self._bar.close()
                self._bar = outer_bar
                self._state = outer
            took = _clock(time.monotonic() - state["start"])
            counted = f"{state['done']} {state['unit']}, " if state["total"] is not None else ""
            if state["spoke"] and not failed:
                print(f"longtime: {name}: done ({counted}{took})", file=self.stream, flush=True)

    def advance(self, count: int = 1, last: str = "", cost: float | None = None) -> None:
        """``count`` more units of the open phase done; ``last`` names the one that ended;
        ``cost``: their estimated cost (a phase opened with ``costs``)."""
        state = self._state
        if not self.on or state is None:
            return
        with self._lock:
            state["done"] += count
            state["cost_done"] += cost or 0.0
            state["last"] = last or state["last"]
            if self._bar is not None:
                left = self._left(state)
                postfix = ", ".join(x for x in (f"about {_clock(left)} left" if left is not None else "", last) if x)
                if postfix:
                    self._bar.set_postfix_str(postfix, refresh=False)
                self._bar.update(count)

    @staticmethod
    def _left(state: dict[str, Any]) -> float | None:
        """The seconds left: the time spent times the estimated cost left over the cost done
        (a phase with ``costs``), else over the units done; None before any is done."""
        took = time.monotonic() - state["start"]
        if not (state["total"] and 0 < state["done"] < state["total"] and took > 0):
            return None
        if state["costs"] and state["cost_done"] > 0:
            return took * max(state["costs"] - state["cost_done"], 0.0) / state["cost_done"]
        return took * (state["total"] - state["done"]) / state["done"]

    def _new_bar(self, state: dict[str, Any]) -> Any:
        from tqdm import tqdm

        if state["total"] is not None and state["costs"]:  # the time left from the costs, in the postfix
            return tqdm(total=state["total"], unit=state["unit"] or "it", desc=state["name"], file=self.stream,
                        dynamic_ncols=True, mininterval=0.5,
                        bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}{postfix}]")
        if state["total"] is not None:
            return tqdm(total=state["total"], unit=state["unit"] or "it", desc=state["name"], file=self.stream,
                        dynamic_ncols=True, mininterval=0.5)
        expected = f" of about {_clock(state['estimate'])}" if (state["estimate"] or 0) >= 1 else ""
        return tqdm(total=None, desc=state["name"], file=self.stream, dynamic_ncols=True, leave=False,
                    bar_format="{desc}: {elapsed}" + expected + (f" ({state['detail']})" if state["detail"] else ""))

    def _line(self, state: dict[str, Any], when: str = "") -> None:
        took = time.monotonic() - state["start"]
        parts = [when] if when else []
        if state["total"] is not None:
            share = f" ({100 * state['done'] / state['total']:.0f} %)" if state["total"] else ""
            parts.append(f"{state['done']} of {state['total']} {state['unit']}{share}")
        parts.append(_clock(took) + (f" of about {_clock(state['estimate'])}" if (state["estimate"] or 0) >= 1 else ""))
        left = self._left(state)
        if left is not None:
            parts.append(f"about {_clock(left)} left")
        if state["detail"]:
            parts.append(state["detail"])
        if state["last"]:
            parts.append(f"last: {state['last']}")
        print(f"longtime: {state['name']}: " + ", ".join(parts), file=self.stream, flush=True)

    def _beat(self, state: dict[str, Any], stop: threading.Event) -> None:
        while not stop.wait(self.every):
            with self._lock:
                if self._state is not state:
                    continue  # a nested phase speaks for now
                state["spoke"] = True
                if self.terminal and self._bar is None:
                    self._bar = self._new_bar(state)
                elif self._bar is not None:
                    self._bar.refresh()
                else:
                    self._line(state)


OFF = Progress(on=False)


class RunProgress:
    """A line on stderr now and then while a long run goes on (never for short ones): the
    run ``label`` (problem x scheme), its time against ``t_final`` from ``t0``."""

    def __init__(self, label: str, t0: float, t_final: float) -> None:
        self.label = label
        self.t0, self.t_final = t0, t_final
        self.start = self.last = time.monotonic()
        self.on = os.environ.get("LONGTIME_PROGRESS", "1") != "0"
        self.shown = False

    def update(self, t: float) -> None:
        now = time.monotonic()
        if self.on and now - self.last >= RUN_SECONDS:
            self.last, self.shown = now, True
            done = (t - self.t0) / (self.t_final - self.t0)
            print(f"longtime: {self.label}: t = {t:.6g} of {self.t_final:.6g} ({100 * done:.0f} %, "
                  f"{now - self.start:.0f} s)", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.shown:
            print(f"longtime: {self.label}: done in {time.monotonic() - self.start:.0f} s",
                  file=sys.stderr, flush=True)
