"""Every bake setting reaches every surface: the BakeSettings field and its validation limits,
bake.py's option, the user guide's table (plain Python, < 1 s). The Blender property of each
setting is checked in tests/blender/test_settings_blender.py."""
import importlib.util
import math
import re
import subprocess
import sys

import pytest

from conftest import REPO
from schnee_probes import settings
from schnee_probes.settings import SETTINGS, BakeError, BakeSettings

GUIDE = REPO / "docs" / "user-guide.md"


def _bake_py_parser():
    spec = importlib.util.spec_from_file_location("bake_py_under_test", REPO / "bake.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)  # bake.py imports bpy only inside main()
    return mod._parser(settings)


def _guide_rows():
    text = GUIDE.read_text(encoding="utf-8")
    block = text[text.index(settings.TABLE_BEGIN):text.index(settings.TABLE_END)]
    rows = {}
    for line in block.splitlines():
        m = re.match(r"\| (.+?) \(`(--[a-z-]+)`\) \| (.+?) \| (.+?) \| (.+) \|$", line)
        if m:
            rows[m.group(2)] = m.groups()
    return rows


def test_names_are_unique_and_the_dataclass_has_exactly_the_settings():
    names = [s.name for s in SETTINGS]
    assert len(names) == len(set(names))
    assert [f.name for f in __import__("dataclasses").fields(BakeSettings)] == names
    d = BakeSettings()
    for s in SETTINGS:
        assert getattr(d, s.name) == s.default, s.name
        assert s.check(s.default) is None, s.name  # every default is valid
    d.validate()


def test_committed_guide_table_equals_the_generated_one():
    proc = subprocess.run([sys.executable, str(REPO / "scripts" / "gen_settings_table.py"), "--check"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


@pytest.mark.parametrize("s", SETTINGS, ids=[s.name for s in SETTINGS])
def test_setting_reaches_every_surface(s):
    # 1. bake.py: one option that sets exactly this field, with the declared choices.
    parser = _bake_py_parser()
    actions = {a.dest: a for a in parser._actions}
    assert s.name in actions, f"bake.py has no option for {s.name}"
    assert s.cli in actions[s.name].option_strings
    if s.kind == "enum":
        sample, expect = s.choice_ids[-1], s.choice_ids[-1]
    elif s.kind == "bool":
        sample, expect = ("off", False) if s.default else ("on", True)
    elif s.kind in ("str", "path"):
        sample = expect = "/tmp/x.shprobe"
    else:
        expect = (int if s.kind == "int" else float)(s.minimum if s.minimum is not None else 3)
        sample = str(expect)
    assert getattr(parser.parse_args([s.cli, sample]), s.name) == expect
    if s.kind == "enum":
        assert tuple(actions[s.name].choices) == s.choice_ids

    # 2. the guide's table: a row naming the label and option, the default and the limits.
    row = _guide_rows().get(s.cli)
    assert row is not None, f"docs/user-guide.md has no settings row for {s.cli}"
    assert row[0] == s.label
    assert row[3] == s.limits_text()
    assert row[2].startswith(s.format_value(s.default))

    # 3. validate: the limits of the declaration, no more, no less.
    def refused(value):
        try:
            BakeSettings(**{s.name: value}).validate()
        except BakeError as exc:
            assert s.label in str(exc) and s.cli in str(exc), str(exc)
            return True
        return False

    if s.kind in ("int", "float"):
        step = 1 if s.kind == "int" else 1e-6
        if s.even:
            step = 2
        if s.minimum is not None:
            lo = s.minimum + (step if s.min_exclusive else 0)
            if s.name == "max_cell_size":
                lo = max(lo, BakeSettings().min_cell_size)  # cross-check: >= Min Cell Size
                assert refused(lo - step)
            else:
                assert not refused(lo) and refused(lo - step)
        if s.maximum is not None:
            assert not refused(s.maximum) and refused(s.maximum + step)
        if s.even:
            assert refused(s.default + 1)
        if s.kind == "float":
            assert refused(math.nan) and refused(math.inf)
    elif s.kind == "enum":
        assert refused("NOT_A_" + s.choice_ids[0])
        for c in s.choice_ids:
            assert not refused(c)
    elif s.kind in ("str", "path"):
        assert refused("")
    elif s.kind == "bool":
        assert not refused(not s.default)


def test_cross_check_max_cell_at_least_min_cell():
    with pytest.raises(BakeError, match="Max Cell Size"):
        BakeSettings(min_cell_size=2.0, max_cell_size=1.0).validate()
    BakeSettings(min_cell_size=2.0, max_cell_size=2.0).validate()


def test_panorama_width_rule_is_one_rule():
    # The drift of issue 10: the property allowed >= 8 (step 2), validate wanted even >= 4.
    s = settings.SETTINGS_BY_NAME["panorama_resolution"]
    assert (s.minimum, s.maximum, s.even) == (4, 4096, True)
    BakeSettings(panorama_resolution=4).validate()
    for bad in (2, 6 + 1, 4098):
        with pytest.raises(BakeError, match="Panorama Resolution"):
            BakeSettings(panorama_resolution=bad).validate()


def test_output_must_be_a_shprobe_path():
    with pytest.raises(BakeError, match=r"\.shprobe"):
        BakeSettings(output_path="//scene.blend").validate()
