"""The diagnosis' result objects: a ``Finding`` (a named cause with its
evidence, the simulator term's parameters and its gain) and the
``Diagnosis`` of one mote's session, with their JSON (numbers rounded to 6
significant digits, NaN and inf as null)."""
from __future__ import annotations

from dataclasses import dataclass, field

from ..jsonable import finite, jsonable
from . import gain as G


@dataclass
class Finding:
    sensor: str
    cause: str
    summary: str
    evidence: dict
    params: dict
    gain: float | None

    def to_json(self) -> dict:
        return {"sensor": self.sensor, "cause": self.cause, "summary": self.summary,
                "evidence": to_jsonable(self.evidence), "params": to_jsonable(self.params),
                "gain": None if self.gain is None else num(self.gain)}


@dataclass
class Diagnosis:
    session: str
    mote: int
    kind: str
    findings: list
    tests: list                    # every test: sensor, cause, p, level, kept
    alpha: float
    n_tests: int
    model: dict                    # the extended simulator model
    start_model: dict              # the paper model fitted to the session
    structures: dict               # sensor -> structure.Structure
    screens: list
    obs: dict
    comparison: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    temperature: dict = field(default_factory=dict)   # sensor -> thermal.TempTest

    @property
    def clean(self) -> bool:
        return not self.findings

    def to_json(self) -> dict:
        """Exactly the issue's form: clean, findings, model."""
        return {"clean": self.clean, "findings": [f.to_json() for f in self.findings],
                "model": self.model}

    def details_json(self) -> dict:
        """Everything else (the --report directory's diagnosis.json)."""
        return to_jsonable({"session": self.session, "mote": self.mote, "kind": self.kind,
                            "alpha": self.alpha, "n_tests": self.n_tests,
                            "per_test_alpha": G.per_test_alpha(self.alpha, self.n_tests),
                            "tests": self.tests, "comparison": self.comparison,
                            "notes": self.notes, "start_model": self.start_model})

    def causes(self) -> set:
        return {(f.sensor, f.cause) for f in self.findings}


def num(x):
    """A JSON number rounded to 6 significant digits (None for NaN/inf)."""
    x = finite(x)
    return None if x is None else float(f"{x:.6g}")


def to_jsonable(x):
    return jsonable(x, num)
