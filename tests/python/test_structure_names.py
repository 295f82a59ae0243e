"""One list of version 3 structure names ("grid", "octree", "tetrahedra"), in the file's order.

The add-on's ``native.STRUCTURES`` is the Python source (gltf_export.py imports it); the C reader's
table (native/src/pb_shprobe.c, indexed by ``pb_shprobe_structure``), the engine's glTF parser's
table (engine/ext/sv_ext.c) and the reader's error message are separate C code, so this test reads
those sources and compares them with it, as tests/engine/ext/test_probe_modes.c does for the probe
modes. A fourth structure therefore fails here until every list has it. Runtime: < 1 s."""
import re

from conftest import REPO
from schnee_probes import native


def _c_string_table(path, name):
    """The string literals of ``static const char *const <name>[] = {...};`` in a C file."""
    text = (REPO / path).read_text()
    m = re.search(r"static const char \*const " + re.escape(name) + r"\[\]\s*=\s*\{([^}]*)\}", text)
    assert m, f"no table {name} in {path}"
    return tuple(re.findall(r'"([^"]*)"', m.group(1)))


def test_python_list_is_the_file_order():
    assert native.STRUCTURES == ("grid", "octree", "tetrahedra")
    # The enum of the C header gives the index of each name in the file's structure field.
    header = (REPO / "native/include/schnee/pb_shprobe.h").read_text()
    enum = dict((k, int(v)) for k, v in re.findall(r"PB_SHPROBE_(GRID|OCTREE|TETRA)\s*=\s*(\d+)", header))
    assert enum == {"GRID": 0, "OCTREE": 1, "TETRA": 2}


def test_exporter_takes_the_native_list():
    text = (REPO / "addon/schnee_probes/gltf_export.py").read_text()
    assert re.search(r"^from \.native import (.*\b)?STRUCTURES\b", text, re.M)
    assert not re.search(r"^STRUCTURES\s*=", text, re.M), "gltf_export.py declares its own STRUCTURES again"


def test_native_reader_table_and_message_match():
    assert _c_string_table("native/src/pb_shprobe.c", "structure_names") == native.STRUCTURES
    text = (REPO / "native/src/pb_shprobe.c").read_text()
    m = re.search(r"unknown structure %u at offset %u; this reader knows ([^\"]*)\"", text)
    assert m, "the reader's unknown-structure message moved"
    assert m.group(1) == ", ".join(f"{i} = {n}" for i, n in enumerate(native.STRUCTURES))


def test_engine_table_matches():
    # The glTF entry names version 4's structure 3 too ("kdtree", gltf_export.V4_STRUCTURES).
    names = _c_string_table("engine/ext/sv_ext.c", "grid_structures")  # (its NULL end is no literal)
    assert names == native.STRUCTURES + ("kdtree",)
    text = (REPO / "addon/schnee_probes/gltf_export.py").read_text()
    assert re.search(r'^V4_STRUCTURES = \("kdtree",\)', text, re.M)
    # sv_ext_grid_structure_name bounds its index by the count.
    text = (REPO / "engine/ext/sv_ext.c").read_text()
    m = re.search(r"sv_ext_grid_structure_name\(uint32_t v\)\s*\{\s*return v < (\d+) \?", text)
    assert m and int(m.group(1)) == len(native.STRUCTURES) + 1
