"""``motecal log``'s screens: plain lines (no TTY) or a live rich panel,
and the keys a person types while guided (Enter, q)."""
from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections import deque

from ..capture.logger import Logger, NullDisplay

POSE_FLOWS = ("static80", "adaptive")     # flows that suggest poses

class PlainDisplay(NullDisplay):
    """Plain lines (no TTY): every event, a status line every ``every`` seconds."""

    def __init__(self, out=None, every: float = 5.0):
        self.out = out or sys.stdout
        self.every = every
        self._next = 0.0
        self._prompted: dict = {}

    def _print(self, text):
        print(text, file=self.out, flush=True)

    def start(self, logger):
        self._print(f"logging {logger.spec} into session {logger.writer.name}"
                    + (f" ({logger.guide.kind}, guided)" if logger.guide else ""))
        self._next = time.monotonic() + self.every

    def event(self, text):
        if text:
            self._print(text)

    def tick(self, logger):
        if logger.guide is not None and not logger.guide.auto:
            for st in logger.guide.status():       # interactive without a TTY for output
                key = (st["mote"], st.get("pose"), st["armed"])
                if st["kind"] in POSE_FLOWS and st["target"] and self._prompted.get(
                        st["mote"]) != key and not st["armed"]:
                    self._prompted[st["mote"]] = key
                    self._print(f"mote {st['mote']}: pose {st['pose']}/{st['poses']}: "
                                f"{st['target']}; hold still and press Enter")
        now = time.monotonic()
        if now >= self._next:
            self._next = now + self.every
            tr = logger.tracker
            total = sum(m.c["samples"] for m in tr.motes.values())
            extra = ""
            if logger.guide is not None:
                parts = []
                for st in logger.guide.status():
                    if st["kind"] == "static80":
                        parts.append(f"mote {st['mote']} pose {st['pose']}/{st['poses']}")
                    elif st["kind"] == "adaptive":
                        parts.append(f"mote {st['mote']} pose {st['pose']} (at most "
                                     f"{st['poses']})" + (f": {st['estimate']}"
                                                          if st["estimate"] else ""))
                    else:
                        parts.append(f"mote {st['mote']} {st['count']}/{st['samples']} "
                                     f"cov {st['coverage']:.0%}")
                extra = "; " + ", ".join(parts)
            temps = ", ".join(f"mote {m} {link.temp_c:.1f} C" for m, link in tr.seen().items()
                              if link.temp_c is not None)
            self._print(f"[{logger.elapsed:6.1f} s] {total} samples, "
                        f"{tr.line['crc_errors']} CRC errors"
                        + ("" if logger.connected else ", reconnecting")
                        + (f"; {temps}" if temps else "") + extra)

    def stop(self, logger):
        for line in logger.summary_lines():
            self._print(line)


class RichDisplay(NullDisplay):
    """Live panel on a terminal (rich): link per mote, guidance, recent events."""

    def __init__(self):
        from rich.console import Console
        self.console = Console()
        self.live = None
        self.events: deque = deque(maxlen=6)
        self._rates: dict = {}
        self._last = 0.0

    def start(self, logger):
        from rich.live import Live
        self.live = Live(self._render(logger), console=self.console, refresh_per_second=4,
                         transient=False)
        self.live.start()

    def event(self, text):
        if text:
            self.events.append(text)

    def tick(self, logger):
        now = time.monotonic()
        if self.live is not None and now - self._last >= 0.25:
            self._last = now
            self.live.update(self._render(logger))

    def stop(self, logger):
        if self.live is not None:
            self.live.update(self._render(logger))
            self.live.stop()
        for line in logger.summary_lines():
            self.console.print(line)

    def _rate(self, mote, samples):
        now = time.monotonic()
        hist = self._rates.setdefault(mote, deque(maxlen=20))
        hist.append((now, samples))
        t0, s0 = hist[0]
        return (samples - s0) / (now - t0) if now > t0 else 0.0

    def _render(self, logger):
        from rich.console import Group
        from rich.panel import Panel
        from rich.table import Table
        from rich.text import Text
        tr = logger.tracker
        table = Table(box=None, pad_edge=False)
        for col in ("mote", "samples", "rate/s", "lost", "dup", "reord", "temp", "status"):
            table.add_column(col, justify="right")
        for m, link in tr.seen().items():
            c = link.c
            table.add_row(str(m), str(c["samples"]), f"{self._rate(m, c['samples']):.0f}",
                          str(c["lost"]), str(c["duplicates"]), str(c["reordered"]),
                          "-" if link.temp_c is None else f"{link.temp_c:.1f} C",
                          f"drop {c['mote_dropped']} late {c['mote_late']}")
        ln = tr.line
        state = "[green]connected[/]" if logger.connected else "[red]reconnecting[/]"
        head = Text.from_markup(
            f"[b]{logger.writer.name}[/]  {logger.spec}  {state}  {logger.elapsed:.0f} s   "
            f"frames {ln['frames']}  CRC err {ln['crc_errors']}  garbage {ln['garbage_bytes']}"
            f"  disconnects {ln['disconnects']}")
        parts = [head, table]
        if logger.guide is not None:
            for st in logger.guide.status():
                parts.append(_guide_text(st))
        if self.events:
            parts.append(Text("\n".join(self.events), style="dim"))
        return Panel(Group(*parts), title="motecal log", subtitle="Ctrl-C ends the session")


def _guide_text(st: dict):
    from rich.text import Text
    lines = []
    if st["kind"] in POSE_FLOWS:
        of = (f"of {st['poses']}" if st["kind"] == "static80" else
              f"(at most {st['poses']}; the first {st['seed_poses']} spread evenly)")
        lines.append(f"mote {st['mote']}: pose {st['pose']} {of}"
                     f" - {st['phase']}"
                     + (f" ({st['captured']}/{st['samples']})" if st["captured"] else ""))
        if st["kind"] == "adaptive":
            lines.append("  promised error: " + (st["estimate"] or "after the seed poses"))
        if st["target"]:
            lines.append(f"  suggested: {st['target']}")
        sketch = st["sketch"]
        cov = [f"coverage {st['coverage']:.0%} (o = suggested)"] + st["map"]
        for k in range(max(len(sketch), len(cov))):
            a = sketch[k] if k < len(sketch) else ""
            b = cov[k] if k < len(cov) else ""
            lines.append(f"  {a:24s} {b}")
        if st["warning"]:
            lines.append(f"  ! {st['warning']}")
    else:
        lines.append(f"mote {st['mote']}: rotation - {st['phase']}: {st['count']}/"
                     f"{st['samples']} samples, coverage {st['coverage']:.0%} "
                     f"(stops at {st['target_coverage']:.0%})"
                     + ("" if st["armed"] else "  -- press Enter to start"))
        lines += ["  " + r for r in st["map"]]
    return Text("\n".join(lines))


@contextlib.contextmanager
def no_echo(active: bool):
    """Keys typed for the guide (Enter) are not echoed into the live display."""
    if not active:
        yield
        return
    import termios
    fd = sys.stdin.fileno()
    old = termios.tcgetattr(fd)
    new = list(old)
    new[3] &= ~termios.ECHO
    termios.tcsetattr(fd, termios.TCSADRAIN, new)
    try:
        yield
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, old)


class KeyReader(threading.Thread):
    """Interactive use: Enter confirms a pose, 'q' + Enter ends the session."""

    def __init__(self, logger: Logger, stream=None):
        super().__init__(daemon=True)
        self.logger = logger
        self.stream = stream or sys.stdin

    def run(self):
        for line in self.stream:
            if line.strip().lower() in ("q", "quit"):
                self.logger.request_stop("quit")
                return
            if self.logger.guide is not None:
                self.logger.guide.arm()
