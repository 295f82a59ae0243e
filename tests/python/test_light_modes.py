"""The light-mode rule of light_modes.py in plain Python (< 1 s): the defaults by lamp type at the
measured radius limit, and the shadow-map layers the engine gives each lamp. The same module in
real Blender (the registered property, the legacy custom property, the panels, the bake and the
export): tests/blender/test_lights.py; in 4.3 and 5.2: tests/blender_versions."""
import math
import re

import pytest

from conftest import REPO
from schnee_probes import light_modes


@pytest.mark.parametrize("kind, radius, mode", [
    ('SUN', 0.0, "mixed"), ('SUN', 5.0, "mixed"),
    ('SPOT', 0.0, "mixed"), ('SPOT', 2.0, "mixed"),
    ('POINT', 0.0, "mixed"), ('POINT', 0.1, "mixed"), ('POINT', 0.25, "mixed"),
    ('POINT', 0.2501, "baked"), ('POINT', 0.5, "baked"),
    ('AREA', 0.25, "baked"), ('', 0.0, "baked"),
])
def test_default_by_type(kind, radius, mode):
    assert light_modes.default_for(kind, radius) == mode


def test_limit_matches_the_measured_table():
    # bench/results/lamp_modes.md (bench/bench_lamp_modes.py): the rows' "default" column is
    # default_for, and the rule agrees with the measured better mode in 31 of 32 rows.
    text = (REPO / "bench" / "results" / "lamp_modes.md").read_text()
    rows = re.findall(r"^\| (Point|Spot|Sun) \| [^|]+ \| ([0-9.]+)(?: m|°) \|.*\| (mixed|baked) \| (mixed|baked) \|$",
                      text, re.M)
    assert len(rows) == 32
    for kind, size, _better, default in rows:
        radius = math.radians(float(size)) if kind == "Sun" else float(size)
        assert light_modes.default_for(kind.upper(), radius) == default, (kind, size)
    assert sum(better == default for _, _, better, default in rows) == 31


def test_shadow_layers_follow_the_engine():
    # docs/engine.md "Shadows": a sun its cascades (4 by default), a point light six, a spot one
    # (six when its outer cone half-angle is over 60°), area lamps are not exported.
    assert light_modes.shadow_layers('SUN') == 4
    assert light_modes.shadow_layers('POINT') == 6
    assert light_modes.shadow_layers('SPOT', math.radians(45.0)) == 1
    assert light_modes.shadow_layers('SPOT', math.radians(120.0)) == 1
    assert light_modes.shadow_layers('SPOT', math.radians(121.0)) == 6
    assert light_modes.shadow_layers('AREA') == 0


def test_engine_constants_mirror_sv_gpu_h():
    # The panel's warning counts with the engine's own numbers (shaders/sv_gpu.h).
    header = (REPO / "shaders" / "sv_gpu.h").read_text()

    def define(name):
        return float(re.search(rf"#define {name}\s+([0-9.]+)f?", header).group(1))
    assert light_modes.ENGINE_SHADOW_LAYERS == define("SV_MAX_SHADOW_LAYERS")
    assert light_modes.ENGINE_SUN_CASCADES == define("SV_SHADOW_DEFAULT_CASCADES")
    assert light_modes.ENGINE_SPOT_CUBE_HALF_ANGLE == pytest.approx(define("SV_SPOT_SHADOW_MAX_ANGLE"), abs=1e-6)
