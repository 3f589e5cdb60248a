"""The force verdict (:class:`Forces`) and the sentences the report and FreeCAD give of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field


from core.forces import joints, limits


@dataclass
class Forces:
    """What :func:`analyse` found.

    ``stable``: every body is held and every utilisation is at most 1.
    ``max_utilisation``: the worst utilisation (inf when some body is
    unsupported).  ``utilisation``: brick id -> the utilisation of what
    holds that brick (the joints under it, or above it for a brick that
    hangs; its own bending), inf for unsupported bricks; a build standing below
    :data:`limits.DARK_BELOW` (past :data:`limits.EXACT_BODIES` bodies, :data:`limits.DETAIL_ABOVE`) gives each
    brick the worst, an upper bound.  ``failing_bricks``:
    ids whose utilisation is above 1, sorted; ``unsupported``: those no
    equilibrium holds.  ``failures``: one dict per failing brick with
    ``brick``, ``layer`` (from 1), ``cell``, ``utilisation`` (None when
    unsupported), ``mode`` ("clutch", "bending", "floats", "tips") and
    ``why``, a sentence.  ``mass_g``: the total mass, loads included.
    """

    stable: bool
    ground: str
    max_utilisation: float
    utilisation: dict[int, float] = field(default_factory=dict)
    failing_bricks: list[int] = field(default_factory=list)
    unsupported: list[int] = field(default_factory=list)
    failures: list[dict] = field(default_factory=list)
    mass_g: float = 0.0
    clutch_n: float = joints.CLUTCH_N
    loads: list[dict] = field(default_factory=list)
    seconds: float = 0.0
    tilt_deg: float = 0.0
    topples: list[dict] = field(default_factory=list)
    unchecked: str | None = None
    sub_structures: int = 0
    bands: int = 0
    bodies: int = 0
    #: the work of the programs solved for it (:func:`solver_work`): the same on any machine
    work: int = 0

    def to_json(self) -> dict:
        """The ``stability.force`` block of report.json (inf written as null)."""
        def num(v: float):
            return None if not math.isfinite(v) else round(float(v), 4)
        return {"stable": None if self.unchecked else bool(self.stable), "ground": self.ground,
                "checked": self.unchecked is None, "unchecked_why": self.unchecked,
                "max_utilisation": num(self.max_utilisation),
                "failing_bricks": list(self.failing_bricks),
                "unsupported_bricks": list(self.unsupported),
                "failures": list(self.failures),
                "utilisation": {str(k): num(v) for k, v in sorted(self.utilisation.items())},
                "mass_g": round(self.mass_g, 2), "clutch_n": self.clutch_n,
                "loads": list(self.loads), "seconds": round(self.seconds, 3),
                "rests_tilted_deg": round(self.tilt_deg, 2),
                "topples": list(self.topples),
                "sub_structures": self.sub_structures, "bands": self.bands,
                "method": (BAND_MEANS if self.bands else SUB_MEANS if self.sub_structures
                           else WHOLE_MEANS),
                "explain": FORCE_MEANS}


#: What the utilisation means, in a builder's words.
FORCE_MEANS = ("Utilisation is how hard the hardest-working joint holding a brick works: the pull on "
               "its studs against the clutch they hold (about 100 g per contact point), or the bending "
               "of the brick against what it takes. Up to 1 the brick holds; above 1 it comes off or "
               "breaks. 'Unsupported' bricks float or tip over whatever their studs do.")


def worst_words(force: dict, digits: int = 2) -> str:
    """The worst utilisation of a ``stability.force`` document in words: "infinite" when
    something floats or tips, "at most X (checked by its N hanging part(s))" when the build
    was checked by its hanging parts, "at most X (checked in N height bands)" when in bands
    (upper bounds both), else the figure."""
    if force["max_utilisation"] is None:
        return "infinite (something floats or tips)"
    worst = f"{force['max_utilisation']:.{digits}f}"
    if force.get("bands"):
        return f"at most {worst} (checked in {force['bands']} height bands)"
    if force.get("sub_structures"):
        return f"at most {worst} (checked by its {force['sub_structures']} hanging part(s))"
    return worst


def verdict_words(force: dict) -> str:
    """A checked ``stability.force`` document's verdict in one clause: "stands on a table with
    120 g: worst joint utilisation 0.31" (what the CLI prints and FreeCAD's Forces holds)."""
    return (f"{'stands' if force['stable'] else 'does not stand'} on a {force['ground']} with "
            f"{force['mass_g']:.0f} g: worst joint utilisation {worst_words(force)}")


#: How the verdict was found: one program of the whole build (or :data:`SUB_MEANS`).
WHOLE_MEANS = "one program of the whole build: the worst utilisation is the least any forces reach"


#: How the verdict of a big build with hanging parts was found (:meth:`_Model._by_parts`).
SUB_MEANS = ("the parts that hang (bricks with a cell over air, what rests on them and the "
             f"{limits.MARGIN_LEVELS} levels of bricks under them) in programs of about {limits.WINDOW_BODIES} "
             "bricks each, standing on the bricks under them, which only press, with no pull "
             "between two such parts; the rest of the build stands in pure compression. Those "
             "forces balance the whole build, so it stands; the worst utilisation is what they "
             "reach, at least the least possible. In a part whose worst is below "
             f"{limits.DETAIL_ABOVE}, every brick is given that worst")


#: How the verdict of a big build that its hanging parts do not settle was found
#: (:meth:`_Model._by_bands`).
BAND_MEANS = ("height bands of about {limits.BAND_BODIES} bricks, top down: each band one program standing "
              "on the bricks under it, whose studs hold, with the forces the bands above put on "
              "its bricks fixed. Those forces balance the whole build, so it stands; the worst "
              "utilisation is what they reach, at least the least possible. Every brick is given "
              "the worst of its band").replace("{limits.BAND_BODIES}", str(limits.BAND_BODIES))


def build_unchecked(verdict: Forces) -> str | None:
    """Why the partial builds of a layout whose verdict is ``verdict`` are not force-checked
    step by step, or None when they are (by :class:`BuildChecker`)."""
    if verdict.unchecked:
        return "the force check of the whole build was skipped, so was each step's"
    return None


def graph_only_why(bodies: int) -> str:
    """Why a build of ``bodies`` bricks and printed parts has steps checked by the brick graph
    only (:meth:`BuildChecker.stands` gave them NaN) when it has too many bodies for the
    programs (:attr:`BuildChecker.why` says it when the time budget ran out instead)."""
    return (f"{bodies} bricks and printed parts: a step that hangs would need a program of the "
            f"partial build, and more than {limits.MAX_BODIES} take minutes each; " + GRAPH_ONLY)


GRAPH_ONLY = ("the steps that need one were checked by the brick graph only (joined to the "
               "ground), the others stand in pure compression")
