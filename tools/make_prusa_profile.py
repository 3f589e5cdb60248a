"""Write the flat PrusaSlicer profile resolved from a vendor bundle.

Usage::

    python tools/make_prusa_profile.py [BUNDLE.ini] [OUT.ini]

Defaults: the bundle installed with the ``prusa-slicer`` on PATH (Debian:
``/usr/share/PrusaSlicer/profiles/PrusaResearch.ini``) and
``core/data/prusa_mk3s_0.20mm_quality_pla.ini``, the fallback profile the
core uses where no bundle is installed.

Slicing does not need this: the core resolves the presets from the
installed bundle at run time (:mod:`core.printing.slicer_profile`).  The committed
fallback was written from PrusaSlicer 2.5's bundle (config_version 1.5.1);
the estimate's coefficients were fitted with it.  The output is also a
config file for ``prusa-slicer --load``.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from core.printing import slicer_profile  # noqa: E402


def main(argv: list[str]) -> int:
    """Write the flat profile; returns the process exit status (2 when there is no bundle)."""
    bundle = Path(argv[0]) if argv else slicer_profile.find_bundle(shutil.which("prusa-slicer"))
    if bundle is None:
        print("no PrusaSlicer vendor bundle found: name one (BUNDLE.ini)", file=sys.stderr)
        return 2
    out = Path(argv[1]) if len(argv) > 1 else slicer_profile.FALLBACK_PROFILE
    text = bundle.read_text(encoding="utf-8")
    flat = slicer_profile.flat_profile(slicer_profile.parse_bundle(text))
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(slicer_profile.render(flat, bundle, slicer_profile.config_version(text)),
                   encoding="utf-8")
    print(f"wrote {out}: {len(flat)} keys")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
