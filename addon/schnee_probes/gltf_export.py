"""glTF exporter user extension: probe grids, per-material SH settings, no probe volumes.

Blender's bundled glTF exporter (io_scene_gltf2, 3.4) instantiates ``glTF2ExportUserExtension``
of every enabled add-on whose module has that attribute, and calls its ``*_hook`` methods while
it gathers the scene. Contract: DESIGN.md §5; user documentation: docs/export.md.

- ``gather_scene_hook``: every ``*.shprobe`` in ``sh_coeffs/`` next to the .blend is validated
  through the native reader, copied to ``sh_coeffs/`` next to the exported file, and listed in
  ``scenes[i].extensions.VULKAN_SCHNEE_engine_properties.shProbeGrids`` (sorted by file name).
- ``gather_material_hook``: ``materials[i].extensions.VULKAN_SCHNEE_materials`` from the material's
  "VS Movable Diffuse" group node; also gives the glTF material the group's base colour, which the
  exporter cannot see inside a node group.
- ``gather_tree_filter_tag_hook``: objects of the probe-volume collection are left out.
- ``gather_node_hook``: each exported punctual light gets ``extensions.VULKAN_SCHNEE_light =
  {"mode": "baked" | "mixed" | "realtime"}`` from its object's ``schnee_light_mode`` (light_modes.py);
  each mesh node whose object chose a probe mode (``Object.schnee_probe.mode``, probe_modes.py) gets
  ``extensions.VULKAN_SCHNEE_node = {"probeMode": ..., "probeRepresentation": ...}``.
- The sky the bake captured (``sh_coeffs/sky.exr`` next to the .blend) is copied likewise and
  listed as ``VULKAN_SCHNEE_engine_properties.sky`` with its radiance SH (L2, engine space).
- The sky's sun the bake split off (Sky Sun "mixed": ``sh_coeffs/sun.json`` next to the .blend)
  becomes a ``KHR_lights_punctual`` directional light with ``VULKAN_SCHNEE_light.mode = "mixed"``
  on a node of its own in every exported scene (``gather_scene_hook``).

The extensions are optional (``extensionsUsed`` only). The "Export Engine Properties" checkbox
(Scene.schnee_gltf_export.enabled, on by default) switches off the extensions and the copy.
Every hook is idempotent: the exporter may call the material hook twice for one material.
"""
import copy
import math
import os
import stat
import tempfile
import urllib.parse

import bpy

from . import compat, light_modes, nodes, probe_modes
from .native import STRUCTURES
from .safe_open import RefusedFile, file_kind, open_regular

EXT_ENGINE = "VULKAN_SCHNEE_engine_properties"
EXT_MATERIALS = "VULKAN_SCHNEE_materials"
EXT_LIGHT = "VULKAN_SCHNEE_light"
EXT_NODE = probe_modes.EXTENSION  # "VULKAN_SCHNEE_node": an object's own probe mode (docs/export.md "Node")
SH_DIR = "sh_coeffs"
SH_SUFFIX = ".shprobe"
DEFAULT_VOLUME_COLLECTION = "ProbeVolumes"
GRID_AXES = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]  # rows: grid X, Y, Z axes; v1 is always identity

# Per-export state lives in export_settings under these keys (a fresh dict per export).
_KEY_GRIDS = "schnee_probe_grids"
_KEY_WARNINGS = "schnee_warnings"
_KEY_SKY = "schnee_sky"
_KEY_SUN = "schnee_sun"
SKY_FILE = "sky.exr"  # bake_core.SKY_FILE_NAME
SUN_FILE = "sun.json"  # bake_core.SUN_FILE_NAME
SUN_FORMAT = "schnee-sky-sun"  # bake_core.SUN_FORMAT
SUN_MAX_BYTES = 1 << 16
SUN_NODE_NAME = "Schnee Sky Sun"
SKY_MAX_BAND = 2
PROBE_MODE_PROPERTY = "schnee_probe_mode"
PROBE_MODES = ("off", "object", "pixel")
# How a material evaluates its probe (docs/ambient-cube.md §4-§5): its custom property
# "schnee_probe_representation"; the engine's name table is compared with this list by
# tests/engine/ext/test_probe_representations.c.
PROBE_REPRESENTATION_PROPERTY = "schnee_probe_representation"
PROBE_REPRESENTATIONS = ("sh", "ambientCube")
# Version 3 files (docs/shprobe-format.md): the entry's "structure" values are native.STRUCTURES
# (imported above), its "storage" values these.
STORAGES = ("float32", "float16")
# Version 4 files (docs/shprobe-format.md "Version 4"): the kd corner tree of boxes with per-axis levels
# (the per-axis Adaptive refinement), structure 3.
V4_STRUCTURES = ("kdtree",)


# --------------------------------------------------------------------------------------------
# Settings and UI



# Blender's exporter writes KHR_lights_punctual intensities in the dialog's Lighting Mode:
# Standard (SPEC) = photometric, W x 683 lm/W (a Sun's W/m2 as lux, a point's W/(4 pi) as cd);
# Unitless (COMPAT) = the same without the 683; Raw = Blender's numbers (a point's W as they are).
# The engine works in Blender's radiometric units (the probes' radiance: a Sun's W/m2, a point's
# W/(4 pi) per sr, Cycles' conventions), so each light carries the factor back (docs/export.md).
PBR_WATTS_TO_LUMENS = 683.0


def light_intensity_scale(kind, export_settings) -> float:
    """VULKAN_SCHNEE_light.intensityScale of a glTF light of type ``kind`` ("directional", "point",
    "spot") written in the export's lighting mode: intensity x scale = Blender's radiometric value."""
    mode = export_settings.get("gltf_lighting_mode", "SPEC")
    if mode == "SPEC":
        return 1.0 / PBR_WATTS_TO_LUMENS
    if mode == "RAW" and kind != "directional":
        return 1.0 / (4.0 * math.pi)
    return 1.0


class SchneeGltfExportSettings(bpy.types.PropertyGroup):
    enabled: bpy.props.BoolProperty(
        name="Export Engine Properties",
        description="Write the Schnee probe grids and per-material SH settings into the glTF "
                    "(optional extensions) and copy the .shprobe files next to it",
        default=True,
    )


class SCHNEE_PT_gltf_export(bpy.types.Panel):
    """Checkbox under File > Export > glTF 2.0 > Exporter Extensions."""
    bl_space_type = 'FILE_BROWSER'
    bl_region_type = 'TOOL_PROPS'
    bl_label = ""
    bl_parent_id = "GLTF_PT_export_user_extensions"
    bl_options = {'HIDE_HEADER'}

    @classmethod
    def poll(cls, context):
        operator = getattr(context.space_data, "active_operator", None)
        return operator is not None and operator.bl_idname == "EXPORT_SCENE_OT_gltf"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = False
        layout.prop(context.scene.schnee_gltf_export, "enabled")


class SCHNEE_OT_export_warning(bpy.types.Operator):
    """Internal: put a warning of the glTF export into Blender's report list (status bar, Info)."""
    bl_idname = "schnee.export_warning"
    bl_label = "Schnee Export Warning"
    bl_options = {'INTERNAL'}

    message: bpy.props.StringProperty()

    def execute(self, context):
        self.report({'WARNING'}, self.message)
        return {'FINISHED'}


def register_panel():
    """Called by the 3.4 exporter when its dialog opens; returns the matching unregister function.

    The panel's parent only exists while io_scene_gltf2 is enabled, hence this on-demand
    registration (the pattern of glTF-Blender-IO's example add-on)."""
    try:
        bpy.utils.register_class(SCHNEE_PT_gltf_export)
    except (RuntimeError, ValueError):
        pass  # already registered by an earlier dialog
    return unregister_panel


def unregister_panel():
    try:
        bpy.utils.unregister_class(SCHNEE_PT_gltf_export)
    except (RuntimeError, ValueError):
        pass


def draw_export(context, layout):
    """Blender 4.2+: the exporter draws user extensions as ``layout.panel``s through this function
    (registered in ``io_scene_gltf2.exporter_extension_layout_draw``); 3.4 uses the panel above."""
    header, body = layout.panel("SCHNEE_gltf_export", default_closed=False)
    header.use_property_split = False
    header.prop(context.scene.schnee_gltf_export, "enabled")
    if body:
        body.label(text="Probe grids (sh_coeffs/*.shprobe) and VS Movable Diffuse settings")


def export_enabled(scene=None):
    """The checkbox value of ``scene`` (default: the context scene); True when it is unset."""
    scene = scene if scene is not None else bpy.context.scene
    settings = getattr(scene, "schnee_gltf_export", None)
    return True if settings is None else bool(settings.enabled)


def volume_collection_name(scene=None):
    """Name of the probe-volume collection: Scene.schnee_probes.volume_collection, else ProbeVolumes."""
    scene = scene if scene is not None else bpy.context.scene
    props = getattr(scene, "schnee_probes", None)
    name = getattr(props, "volume_collection", None)
    if isinstance(name, str) and name:
        return name
    coll = getattr(name, "name", None)  # tolerate a PointerProperty to the collection
    return coll or DEFAULT_VOLUME_COLLECTION


# --------------------------------------------------------------------------------------------
# Helpers


def _warn(export_settings, message):
    """A warning the user must see: exporter console, Blender's report list, export_settings."""
    message = "Schnee glTF export: " + message
    warnings = export_settings.setdefault(_KEY_WARNINGS, [])
    if message in warnings:
        return  # hooks may run twice; say it once
    warnings.append(message)
    log = export_settings.get("log")
    if log is not None and hasattr(log, "warning"):
        log.warning(message)  # 4.2+: the exporter shows its log as operator reports
        return
    try:
        from io_scene_gltf2.io.com.gltf2_io_debug import print_console
        print_console('WARNING', message)
    except ImportError:
        print("WARNING: " + message)
    # 3.4 has no report channel for hooks: an internal operator puts it into Blender's report list.
    try:
        bpy.ops.schnee.export_warning(message=message)
    except Exception:  # the operator is missing (add-on half-registered): the console line stays
        pass


def _f32(value):
    """Shortest decimal that reads back as the same float32 (header floats are float32)."""
    import numpy as np
    return float(np.format_float_positional(np.float32(value), unique=True, trim='-'))


def _make_extension(name, payload):
    try:
        from io_scene_gltf2.io.com.gltf2_io_extensions import Extension  # 3.4 .. 4.2
    except ImportError:
        from io_scene_gltf2.io.com.extensions import Extension  # 4.3+ renamed the modules
    return Extension(name=name, extension=payload, required=False)


def _blend_sh_dir():
    if not bpy.data.filepath:
        return None  # unsaved .blend: there is no "next to the .blend"
    return os.path.join(os.path.dirname(os.path.abspath(bpy.data.filepath)), SH_DIR)


def _copy_atomic(src, dst, checked):
    """Copy ``src`` to ``dst`` through a temporary file in the same folder (never a partial file).

    ``checked`` is the ``os.stat`` of ``src`` taken before its content was validated: the file is
    opened without blocking, regular files only (safe_open.open_regular: a path replaced by a FIFO
    or a device meanwhile is refused at once, never read), and copied only if it is still that
    file (device, inode, size, modification time), at most its checked size. Anything else raises
    :class:`RefusedFile` (an OSError) naming ``src``."""
    if os.path.exists(dst) and os.path.samefile(src, dst):
        return  # exporting next to the .blend: the file is already where it belongs
    inp, size = open_regular(src, "a file to export", 1 << 62)  # reads no more than the checked size (below)
    with inp:
        st = os.fstat(inp.fileno())
        if (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns) != \
                (checked.st_dev, checked.st_ino, checked.st_size, checked.st_mtime_ns):
            raise RefusedFile(f"{src}: the file changed after it was checked; not copied", "I/O error")
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=os.path.splitext(dst)[1], dir=os.path.dirname(dst))
        try:
            with os.fdopen(fd, "wb") as out:
                copied = 0
                while copied < size:
                    chunk = inp.read(min(1 << 20, size - copied))
                    if not chunk:
                        raise RefusedFile(f"{src}: the file shrank while it was copied; not copied", "I/O error")
                    out.write(chunk)
                    copied += len(chunk)
            os.chmod(tmp, stat.S_IMODE(st.st_mode))  # mkstemp creates 0600; keep the source's permissions
            os.replace(tmp, dst)
        except BaseException:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            raise


def _regular_stat(path):
    """(os.stat of ``path``, None) for a regular file (symbolic links followed), else (None, why):
    stat never blocks, so a FIFO, a device, a folder or a symbolic link loop is named, not opened."""
    try:
        st = os.stat(path)
    except OSError as exc:
        return None, f"cannot read it: {exc.strerror}"
    if not stat.S_ISREG(st.st_mode):
        return None, f"not a regular file (a {file_kind(st.st_mode)})"
    return st, None


def _grid_entry(path, header, probes=None):
    """The shProbeGrids entry of one file (DESIGN.md §5) from its validated header; for a version 3
    file also ``version``, ``structure``, ``representation`` and ``storage`` from the whole file
    ``probes`` (native.read_shprobe). Versions 1 and 2 keep exactly their entry of before."""
    name = os.path.splitext(os.path.basename(path))[0]
    dims = [int(d) for d in header["grid_dims"]]
    origin = [_f32(v) for v in header["grid_origin"]]
    spacing = _f32(header["grid_spacing"])
    if len(dims) != 3 or len(origin) != 3:
        raise ValueError("header grid_dims/grid_origin do not have 3 components")
    # Version 1 grids are axis-aligned (the reader reports identity); version 2 may rotate them.
    axes = [[_f32(v) for v in row] for row in header.get("grid_axes", GRID_AXES)]
    if len(axes) != 3 or any(len(row) != 3 for row in axes):
        raise ValueError("header grid_axes is not 3x3")
    if not all(math.isfinite(v) for v in origin + [spacing] + sum(axes, [])):
        raise ValueError("header grid origin, spacing or axes are not finite")
    return {
        "name": name,
        "uri": SH_DIR + "/" + urllib.parse.quote(os.path.basename(path)),
        "probeCount": int(header["probe_count"]),
        "maxBand": int(header["max_band"]),
        "gridOrigin": origin,
        "gridDims": dims,
        "gridSpacing": spacing,
        "gridAxes": axes,
        **_v3_fields(header, probes),
    }


def _v3_fields(header, probes):
    """Versions 3 and 4 (docs/export.md): the interpolation structure, what the records hold and how.
    For an octree gridOrigin / gridSpacing / gridDims are the lattice origin, Min Cell Size and the
    lattice extent in min cells; for tetrahedra gridDims is [0, 0, 0]."""
    version = int(header["version"])
    if version < 3 or probes is None:
        return {}
    known = STRUCTURES if version == 3 else V4_STRUCTURES
    if version > 4 or probes.structure not in known or probes.representation not in PROBE_REPRESENTATIONS \
            or probes.storage not in STORAGES:
        raise ValueError(f"unknown version {version} layout: structure {probes.structure!r}, representation "
                         f"{probes.representation!r}, storage {probes.storage!r}")
    return {"version": version, "structure": probes.structure, "representation": probes.representation,
            "storage": probes.storage}


def collect_probe_grids(export_settings):
    """Validate and copy the .shprobe files once per export; return the shProbeGrids entries.

    A file the native reader rejects (or that cannot be copied) gets a warning and no entry.
    The result is cached in ``export_settings`` so repeated hook calls copy and warn once.
    """
    if _KEY_GRIDS in export_settings:
        return export_settings[_KEY_GRIDS]
    entries = []
    export_settings[_KEY_GRIDS] = entries

    src_dir = _blend_sh_dir()
    if src_dir is None or not os.path.isdir(src_dir):
        return entries
    # Every *.shprobe name: one that is not a regular file (a FIFO, a device, a folder, a symbolic
    # link loop) is skipped with a warning that names it, never opened.
    files = sorted(f for f in os.listdir(src_dir) if f.endswith(SH_SUFFIX))
    if not files:
        return entries

    try:
        from . import native
    except Exception as exc:  # noqa: BLE001 - any import failure means "no reader"
        _warn(export_settings, f"the native module cannot be loaded ({exc}); "
                               f"{len(files)} .shprobe file(s) in {src_dir} not exported")
        return entries

    dst_dir = os.path.join(os.path.dirname(os.path.abspath(export_settings["gltf_filepath"])), SH_DIR)
    for fname in files:
        src = os.path.join(src_dir, fname)
        checked, why = _regular_stat(src)
        if checked is None:
            _warn(export_settings, f"skipped {src}: {why}")
            continue
        try:
            header = native.read_shprobe_header(src)
            # The header alone passes a file whose body the engine would refuse (grid entries out
            # of range, NaN coefficients): validate all of it with the same reader.
            entry = _grid_entry(src, header, native.read_shprobe(src))
        except Exception as exc:  # noqa: BLE001 - SchneeError, OSError, bad header values, ...
            reason = str(exc)
            _warn(export_settings, "skipped " + (reason if src in reason else f"{src}: {reason}"))
            continue
        try:
            os.makedirs(dst_dir, exist_ok=True)
            _copy_atomic(src, os.path.join(dst_dir, fname), checked)
        except RefusedFile as exc:
            _warn(export_settings, f"skipped {exc}")
            continue
        except OSError as exc:
            _warn(export_settings, f"skipped {src}: cannot copy to {dst_dir}: {exc}")
            continue
        entries.append(entry)
    return entries


def _sidecar(export_settings, key, file_name, what):
    """(path, its checked stat) of the regular file ``file_name`` in the bake's sh_coeffs/ next to
    the .blend, or (None, None): absent, or not a regular file (warned, naming ``what``). Marks
    ``key`` done (None) in the export's cache first, so a failed file is looked at once."""
    export_settings[key] = None
    src_dir = _blend_sh_dir()
    src = os.path.join(src_dir, file_name) if src_dir else None
    if src is None or not os.path.lexists(src):
        return None, None
    checked, why = _regular_stat(src)
    if checked is None:
        _warn(export_settings, f"skipped {what} {src}: {why}")
        return None, None
    return src, checked


def collect_sky(export_settings):
    """The ``sky`` member (or None): ``sh_coeffs/sky.exr`` next to the .blend, projected to L2
    radiance SH by the native code (negative texels clamped, as the bake does) and copied next to
    the export. Cached per export like the grids."""
    if _KEY_SKY in export_settings:
        return export_settings[_KEY_SKY]
    src, checked = _sidecar(export_settings, _KEY_SKY, SKY_FILE, "the sky")
    if src is None:
        return None
    try:
        from . import native
        sh = native.project_file(src, SKY_MAX_BAND, negative="clamp")
    except Exception as exc:  # noqa: BLE001 - unreadable image, missing module, ...
        _warn(export_settings, f"skipped the sky {src}: {exc}")
        return None
    dst_dir = os.path.join(os.path.dirname(os.path.abspath(export_settings["gltf_filepath"])), SH_DIR)
    try:
        os.makedirs(dst_dir, exist_ok=True)
        _copy_atomic(src, os.path.join(dst_dir, SKY_FILE), checked)
    except RefusedFile as exc:
        _warn(export_settings, f"skipped the sky {exc}")
        return None
    except OSError as exc:
        _warn(export_settings, f"skipped the sky {src}: cannot copy to {dst_dir}: {exc}")
        return None
    sky = {"uri": SH_DIR + "/" + SKY_FILE, "maxBand": SKY_MAX_BAND,
           "sh": [[_f32(v) for v in row] for row in sh]}
    export_settings[_KEY_SKY] = sky
    return sky


def _sun_fields(data):
    """(direction, irradiance, angle) of a sun.json dict, or raise ValueError saying what is wrong."""
    import numpy as np
    if not isinstance(data, dict) or data.get("format") != SUN_FORMAT or data.get("version") != 1:
        raise ValueError(f"not a version 1 '{SUN_FORMAT}' file")
    if data.get("mode") != "mixed":
        raise ValueError(f"mode {data.get('mode')!r} is not 'mixed'")

    def vec(key):
        v = data.get(key)
        if not (isinstance(v, list) and len(v) == 3 and all(isinstance(x, (int, float)) and
                                                            not isinstance(x, bool) for x in v)):
            raise ValueError(f"{key} is not 3 numbers")
        a = np.asarray(v, dtype=np.float64)
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{key} is not finite")
        return a
    direction, irradiance = vec("direction"), vec("irradiance")
    if abs(float(np.linalg.norm(direction)) - 1.0) > 1e-6:
        raise ValueError("direction is not a unit vector")
    if np.any(irradiance < 0.0) or not float(irradiance.max()) > 0.0:
        raise ValueError("irradiance is not >= 0 with a positive channel")
    angle = data.get("angle")
    if not isinstance(angle, (int, float)) or isinstance(angle, bool) or not (0.0 <= angle < math.pi):
        raise ValueError("angle is not in [0, pi)")
    return direction, irradiance, float(angle)


def _quaternion_minus_z_to(d):
    """glTF rotation [x, y, z, w] turning the node's -Z onto unit vector ``d`` (shortest arc)."""
    v0 = (0.0, 0.0, -1.0)
    cross = (v0[1] * d[2] - v0[2] * d[1], v0[2] * d[0] - v0[0] * d[2], v0[0] * d[1] - v0[1] * d[0])
    w = 1.0 + (v0[0] * d[0] + v0[1] * d[1] + v0[2] * d[2])
    if w < 1e-9:  # d = +Z: half a turn about X
        return [1.0, 0.0, 0.0, 0.0]
    n = math.sqrt(cross[0] ** 2 + cross[1] ** 2 + cross[2] ** 2 + w * w)
    return [cross[0] / n, cross[1] / n, cross[2] / n, w / n]


def collect_sun(export_settings):
    """The sky's sun (or None): ``sh_coeffs/sun.json`` next to the .blend, written by a bake with Sky
    Sun "mixed" (docs/export.md "The sky's sun"), checked and turned into the glTF light's values:
    dict(name, color, intensity, intensity_scale, angle, rotation). Cached per export."""
    if _KEY_SUN in export_settings:
        return export_settings[_KEY_SUN]
    src, _ = _sidecar(export_settings, _KEY_SUN, SUN_FILE, "the sky's sun")
    if src is None:
        return None
    try:
        import json
        f, _ = open_regular(src, "a sun.json", SUN_MAX_BYTES)
        with f:
            data = json.loads(f.read(SUN_MAX_BYTES).decode("utf-8"))
        direction, irradiance, angle = _sun_fields(data)
    except (OSError, ValueError, UnicodeDecodeError) as exc:  # RefusedFile, JSONDecodeError: both ValueError/OSError
        _warn(export_settings, f"skipped the sky's sun {src}: {exc}")
        return None
    scale = light_intensity_scale("directional", export_settings)
    peak = float(irradiance.max())
    # The exporter's lamps carry Blender's W/m² in the dialog's lighting mode (x 683 lux per W/m² in
    # Standard) and VULKAN_SCHNEE_light.intensityScale takes it back: the same for this light.
    sun = dict(name=SUN_NODE_NAME, color=[_f32(v / peak) for v in irradiance], intensity=peak / scale,
               intensity_scale=scale, angle=angle, rotation=_quaternion_minus_z_to(direction))
    export_settings[_KEY_SUN] = sun
    return sun


def _sun_strength(data):
    """The irradiance (W/m²) Cycles renders for Sun lamp ``data``: Strength x the constant Strength
    of the Emission node at its light output x 2^exposure; None when nodes drive it. Blender's
    exporter writes a Sun with an Emission node at the node's Strength alone, without the lamp's
    own (io_scene_gltf2 lights.py __gather_intensity, 3.4 - 5.2); from 5.0 every new lamp has such a
    node tree, so every Sun exported at 1 W/m² (683 lux) whatever its strength."""
    s = 1.0
    tree = data.node_tree if getattr(data, "use_nodes", True) else None
    if tree is not None:
        outs = [n for n in tree.nodes if n.type == 'OUTPUT_LIGHT' and getattr(n, "is_active_output", True)]
        surface = outs[0].inputs.get("Surface") if outs else None
        if surface is None or not surface.is_linked:
            return None   # no emission at all: the exporter's value stays
        node = surface.links[0].from_node
        if node.type != 'EMISSION' or node.inputs["Strength"].is_linked:
            return None
        s = float(node.inputs["Strength"].default_value)
    return float(data.energy) * s * 2.0 ** float(getattr(data, "exposure", 0.0))


def _sun_node(sun):
    """A new glTF node holding the sky's sun as a directional light (KHR_lights_punctual, the light
    itself a child of the root list like the exporter's own lamps)."""
    from io_scene_gltf2.io.com import gltf2_io  # the glTF schema classes (3.4 .. 5.x)
    try:
        from io_scene_gltf2.io.com.gltf2_io_extensions import ChildOfRootExtension, Extension
    except ImportError:
        from io_scene_gltf2.io.com.extensions import ChildOfRootExtension, Extension
    light = {"name": sun["name"], "type": "directional", "color": sun["color"], "intensity": sun["intensity"],
             "extensions": {EXT_LIGHT: Extension(name=EXT_LIGHT, required=False, extension={
                 "mode": "mixed", "intensityScale": sun["intensity_scale"], "source": "sky",
                 "angle": sun["angle"]})}}
    khr = Extension(name="KHR_lights_punctual", required=False, extension={
        "light": ChildOfRootExtension(name="KHR_lights_punctual", path=["lights"], extension=light,
                                      required=False)})   # optional: a viewer without lights ignores it
    return gltf2_io.Node(camera=None, children=[], extensions={"KHR_lights_punctual": khr}, extras=None,
                         matrix=None, mesh=None, name=sun["name"], rotation=list(sun["rotation"]), scale=None,
                         skin=None, translation=None, weights=None)


def material_settings(blender_material, export_settings=None):
    """``VULKAN_SCHNEE_materials`` of a material, or None when it has nothing to say:
    ``shScale``/``ambientTerm`` from its "VS Movable Diffuse" node, ``probeMode`` and
    ``probeRepresentation`` from its custom properties (any material: a large static wall samples
    the grid per pixel without being movable)."""
    out = {}
    node = nodes.find_movable_diffuse_node(blender_material)
    if node is not None:
        out["shScale"] = _f32(node.inputs[nodes.INPUT_SH_SCALE].default_value)
        out["ambientTerm"] = _f32(node.inputs[nodes.INPUT_AMBIENT].default_value)
    # Probe lighting mode (docs/engine.md): the material's custom property "schnee_probe_mode",
    # "off" | "object" | "pixel"; absent = the engine's default (object).
    mode = blender_material.get(PROBE_MODE_PROPERTY) if hasattr(blender_material, "get") else None
    if isinstance(mode, str) and mode in PROBE_MODES:
        out["probeMode"] = mode
    elif mode is not None and export_settings is not None:
        _warn(export_settings, f"material '{blender_material.name}': custom property "
              f"{PROBE_MODE_PROPERTY} = {mode!r} is not one of {', '.join(PROBE_MODES)}; ignored")
    # Probe representation (docs/ambient-cube.md §4 "glTF"): "sh" | "ambientCube"; absent = sh.
    rep = blender_material.get(PROBE_REPRESENTATION_PROPERTY) if hasattr(blender_material, "get") else None
    if isinstance(rep, str) and rep in PROBE_REPRESENTATIONS:
        out["probeRepresentation"] = rep
    elif rep is not None and export_settings is not None:
        _warn(export_settings, f"material '{blender_material.name}': custom property "
              f"{PROBE_REPRESENTATION_PROPERTY} = {rep!r} is not one of {', '.join(PROBE_REPRESENTATIONS)}; "
              f"ignored")
    return out or None


# --------------------------------------------------------------------------------------------
# The exporter extension


class glTF2ExportUserExtension:
    """Hooks called by io_scene_gltf2 (3.4 signatures: glTF object, Blender data, export_settings)."""

    def __init__(self):
        # Read once per export, from the scene the export starts in (the checkbox lives there).
        self.enabled = export_enabled()

    def gather_tree_filter_tag_hook(self, vtree, export_settings):
        """Untag the probe-volume objects: the exporter then drops them and re-parents children."""
        coll = bpy.data.collections.get(volume_collection_name(bpy.context.scene))
        if coll is None:
            return
        volumes = set(coll.all_objects)
        for vnode in vtree.nodes.values():
            if vnode.blender_object in volumes:
                vnode.keep_tag = False

    def gather_scene_hook(self, gltf2_scene, blender_scene, export_settings):
        if not self.enabled:
            return
        grids = collect_probe_grids(export_settings)
        sky = collect_sky(export_settings)
        sun = collect_sun(export_settings)
        if sun is not None and not any(getattr(n, "name", None) == SUN_NODE_NAME and
                                       getattr(n, "extensions", None) for n in gltf2_scene.nodes):
            try:
                gltf2_scene.nodes.append(_sun_node(sun))   # once per scene, however often called
            except (ImportError, TypeError) as exc:       # an exporter whose classes differ
                _warn(export_settings, f"the sky's sun could not be added as a light: {exc}")
        if gltf2_scene.extensions is None:
            gltf2_scene.extensions = {}
        if not grids and sky is None:
            gltf2_scene.extensions.pop(EXT_ENGINE, None)
            return
        # A fresh payload per call: replacing (not appending) keeps a repeated call harmless.
        payload = {"shProbeGrids": copy.deepcopy(grids)}
        if sky is not None:
            payload["sky"] = copy.deepcopy(sky)
        gltf2_scene.extensions[EXT_ENGINE] = _make_extension(EXT_ENGINE, payload)

    def gather_node_hook(self, gltf2_node, blender_object, export_settings):
        """The light mode of a lamp's node: VULKAN_SCHNEE_light inside its KHR_lights_punctual light.

        Blender 3.4 has no hook for the light itself; the node hook sees it as the node's
        ``KHR_lights_punctual`` extension, whose ``light`` member wraps the light dict until the
        exporter moves it into the root ``lights`` list (deduplicated by value)."""
        if not self.enabled or blender_object is None:
            return
        _export_probe_mode(gltf2_node, blender_object, export_settings)
        if getattr(blender_object, "type", None) != 'LIGHT':
            return
        khr = (gltf2_node.extensions or {}).get("KHR_lights_punctual")
        ref = getattr(khr, "extension", None)
        ref = ref.get("light") if isinstance(ref, dict) else None
        if ref is None or not isinstance(getattr(ref, "extension", None), dict):
            return  # not exported as a punctual light (area lights, "Punctual Lights" off)
        try:
            mode = light_modes.light_mode(blender_object)
        except light_modes.LightModeError as exc:
            # The bake refuses such a value; an export still writes a valid file and says why.
            _warn(export_settings, f"{exc}; exported as '{light_modes.DEFAULT}'")
            mode = light_modes.DEFAULT
        # The exporter caches one light dict per light datablock and shares it between objects;
        # a copy per node lets two objects of one datablock differ (they become two lights, the
        # same ones again when equal). Replacing the member keeps a repeated call harmless.
        light = dict(ref.extension)
        extensions = dict(light.get("extensions") or {})
        scale = light_intensity_scale(light.get("type"), export_settings)
        extensions[EXT_LIGHT] = _make_extension(EXT_LIGHT, {"mode": mode, "intensityScale": scale})
        if light.get("type") == "directional":
            strength = _sun_strength(blender_object.data)
            if strength is not None:
                light["intensity"] = strength / scale
        light["extensions"] = extensions
        ref.extension = light

    def gather_material_hook(self, gltf2_material, blender_material, export_settings):
        blender_material = compat.gltf_original_material(blender_material)
        node = nodes.find_movable_diffuse_node(blender_material)
        if node is not None and nodes.feeds_active_output(node):
            _export_base_color(gltf2_material, node, blender_material, export_settings)
        if not self.enabled:
            return
        settings = material_settings(blender_material, export_settings)
        if settings is None:
            return
        if gltf2_material.extensions is None:
            gltf2_material.extensions = {}
        gltf2_material.extensions[EXT_MATERIALS] = _make_extension(EXT_MATERIALS, settings)


def _export_probe_mode(gltf2_node, blender_object, export_settings):
    """The object's own probe mode on its mesh node: ``VULKAN_SCHNEE_node`` (docs/export.md "Node"),
    absent for "As Its Materials Say". Replacing (or removing) the member keeps a repeated call
    harmless."""
    if getattr(gltf2_node, "mesh", None) is None:
        return  # no mesh on this node: nothing to light
    try:
        fields = probe_modes.node_fields(blender_object)
    except probe_modes.ProbeModeError as exc:  # a choice this add-on does not know (a later version's)
        _warn(export_settings, f"object '{blender_object.name}': {exc}; exported as its materials say")
        fields = None
    if fields is None:
        if gltf2_node.extensions:
            gltf2_node.extensions.pop(EXT_NODE, None)
        return
    if gltf2_node.extensions is None:
        gltf2_node.extensions = {}
    gltf2_node.extensions[EXT_NODE] = _make_extension(EXT_NODE, fields)


def _export_base_color(gltf2_material, node, blender_material, export_settings):
    """The group is the surface shader: give glTF its albedo (the exporter only looks at top-level
    Principled BSDFs, so it would otherwise write white, metallic 1)."""
    from io_scene_gltf2.io.com import gltf2_io
    pbr = gltf2_material.pbr_metallic_roughness
    if pbr is None:
        pbr = gltf2_io.MaterialPBRMetallicRoughness(
            base_color_factor=None, base_color_texture=None, extensions=None, extras=None,
            metallic_factor=None, metallic_roughness_texture=None, roughness_factor=None)
        gltf2_material.pbr_metallic_roughness = pbr
    socket = node.inputs[nodes.INPUT_BASE_COLOR]
    if socket.is_linked:
        texture = _base_color_texture(socket, export_settings)
        if texture is not None:
            pbr.base_color_texture = texture
            pbr.base_color_factor = None
        else:
            _warn(export_settings, f"material '{blender_material.name}': the Base Color of "
                                   f"'{node.name}' is linked to something other than an image "
                                   f"texture; exported with its unlinked value")
    if not socket.is_linked or pbr.base_color_texture is None:
        rgba = [min(max(float(c), 0.0), 1.0) for c in socket.default_value]
        pbr.base_color_factor = None if rgba == [1.0, 1.0, 1.0, 1.0] else rgba
    pbr.metallic_factor = 0.0  # a diffuse surface; glTF's default would be 1
    pbr.roughness_factor = None  # glTF default 1.0


def _base_color_texture(socket, export_settings):
    """The exporter's own texture gathering applied to the group's Base Color socket, or None."""
    gather = compat.gltf_gather_texture_info()
    if gather is None:
        return None
    try:
        result = gather(socket, (socket,), export_settings)
    except Exception:  # noqa: BLE001 - exporter internals differ between versions
        return None
    texture = result[0] if isinstance(result, tuple) else result
    return texture


# --------------------------------------------------------------------------------------------

_classes = (SchneeGltfExportSettings, SCHNEE_OT_export_warning)


def _layout_draw_registry():
    """4.2+ exporter's dict of user-extension draw functions; None on 3.4 (it uses register_panel)."""
    return compat.gltf_layout_draw_registry()


def register():
    for cls in _classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.schnee_gltf_export = bpy.props.PointerProperty(type=SchneeGltfExportSettings)
    registry = _layout_draw_registry()
    if registry is not None:
        registry[__package__] = draw_export


def unregister():
    registry = _layout_draw_registry()
    if registry is not None:
        registry.pop(__package__, None)
    unregister_panel()
    del bpy.types.Scene.schnee_gltf_export
    for cls in reversed(_classes):
        bpy.utils.unregister_class(cls)
