"""The benchmark rows and their targets: one table for ``make bench-check`` and the notes.

Each :class:`Row` is one command-line run as a user types it, timed whole (wall
seconds, peak memory) in a fresh process on an idle 2-core machine.  ``target_s``
and ``target_gb`` are what the row must stay under (issue 44's figures where it
gives them; its 188k-triangle figure x5 is not among the shared models, so the eyes
panel and the benchy, small objects that stand with room to spare, take its 5 s and
3 s).  ``quick`` rows make up ``make bench-check`` (about three minutes);
``--all`` adds the long ones.  ``reference.json`` beside this file holds the
stage seconds of the last run that was measured and committed, so a row over its
target names the stage that grew.
"""

from __future__ import annotations

from dataclasses import dataclass, field

#: The demo's high-res boxes (the Makefile's DEMO_HIGH_RES): the two lens mounts.
DEMO_HIGH_RES = ("--high-res=-54,25,25.5,-9,36,70.5", "--high-res=9,25,25.5,54,36,70.5")


@dataclass(frozen=True)
class Row:
    """One benchmark run: ``model`` is a file of ../shared/models, ``demo`` (the bundled
    example, built by ``make demo``), ``cube20`` / ``cube1m`` / ``cube2m`` (boxes made for
    the run) or None (``args`` alone, no output folder).  ``cache``: ``cold`` slices with an
    empty slice cache, ``warm`` runs once first and times the second run (the cache and
    the compiled code warm), ``none`` switches the cache off."""

    name: str
    model: str | None
    args: tuple[str, ...]
    target_s: float
    quick: bool
    target_gb: float | None = None
    cache: str = "cold"
    env: dict = field(default_factory=dict)


ROWS = (
    Row("--help", None, ("--help",), 1.0, True),
    Row("20 mm cube", "cube20", ("--no-picture", "--quiet"), 1.0, True),
    Row("demo, slice cache warm", "demo", DEMO_HIGH_RES, 15.0, True, cache="warm"),
    Row("demo, slice cache empty", "demo", DEMO_HIGH_RES, 40.0, True),
    Row("Relativty eyes panel, default", "relativty_eyes_panel_open.stl", (), 5.0, True),
    Row("Relativty eyes panel, fast", "relativty_eyes_panel_open.stl", ("--effort", "fast"), 3.0, True),
    Row("3DBenchy x2, default", "3dbenchy.3mf", ("--scale", "2"), 5.0, True),
    Row("Relativty HMD body x2, default", "relativty_hmd_body.stl", ("--scale", "2"), 40.0, False),
    Row("Relativty HMD body x2, fast", "relativty_hmd_body.stl", ("--scale", "2", "--effort", "fast"),
        20.0, False),
    Row("Stanford bunny x2, default", "stanford_bunny_open.obj", ("--units", "m", "--scale", "2"),
        40.0, False),
    Row("solid cube 1 m, default", "cube1m", (), 40.0, False, target_gb=1.5),
    Row("solid cube 2 m, default", "cube2m", (), 150.0, False),
)
