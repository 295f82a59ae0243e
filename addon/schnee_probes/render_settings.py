"""Save, override and restore the scene state a bake touches.

A bake changes render, Cycles, image and view-layer settings, the scene camera and some objects'
visibility flags. Every such change goes through one :class:`StateGuard`, which records the old
state before anything changes and puts it back afterwards, on success, error and cancel alike:
the bake itself (``bake_core.ProbeBake``), the sky capture and placement's render evaluation
(:class:`RenderEvaluation`) all use it.
"""
import time

import bpy

from . import compat
from .settings import BakeError

CYCLES_DISABLED = ("The probes are rendered with Cycles, but the Cycles add-on is disabled: enable it in "
                   "Preferences > Add-ons (Render: Cycles Render Engine)")


def require_cycles(scene):
    """``scene.cycles``; :class:`BakeError` saying what to do when the Cycles add-on is disabled
    (then the scene has no Cycles settings and 'CYCLES' is no render engine)."""
    cycles = compat.cycles_settings(scene)
    if cycles is None:
        raise BakeError(CYCLES_DISABLED)
    return cycles

# Nested pointers followed when snapshotting; others (ID pointers, collections) are kept by value
# or skipped. Depth is bounded so cyclic RNA paths cannot recurse forever.
_MAX_DEPTH = 3
# Pointers into scene structure rather than settings.
_SKIP = {"rna_type", "depsgraph", "layer_collection", "active_layer_collection", "active_aov",
         "active_lightgroup",
         # Reading these warns when their stored value is unavailable in this build (no OIDN,
         # unset colour space); the bake never writes them.
         "denoiser", "preview_denoiser", "linear_colorspace_settings"}


def _snapshot(struct, depth=0):
    """{identifier: value or nested snapshot} of the writable, non-ID properties of ``struct``."""
    out = {}
    for prop in struct.bl_rna.properties:
        ident = prop.identifier
        if ident in _SKIP:
            continue
        if prop.type == 'POINTER':
            if prop.is_readonly and depth < _MAX_DEPTH:
                sub = getattr(struct, ident, None)
                if sub is not None and not isinstance(sub, bpy.types.ID):
                    out[ident] = ("STRUCT", _snapshot(sub, depth + 1))
            elif not prop.is_readonly:
                out[ident] = ("VALUE", getattr(struct, ident))
            continue
        if prop.type == 'COLLECTION' or prop.is_readonly:
            continue
        value = getattr(struct, ident)
        if getattr(prop, "is_array", False):
            value = tuple(value)
        out[ident] = ("VALUE", value)
    return out


def _restore(struct, snap):
    """Write back the values of ``snap`` that differ now; returns the identifiers that failed."""
    failed = []
    for ident, (kind, value) in snap.items():
        try:
            if kind == "STRUCT":
                failed += [ident + "." + f for f in _restore(getattr(struct, ident), value)]
                continue
            current = getattr(struct, ident)
            if isinstance(value, tuple):
                current = tuple(current)
            if current != value:
                setattr(struct, ident, value)
        except (AttributeError, TypeError, ValueError):
            failed.append(ident)
    return failed


def _plain(value):
    """A value detached from Blender's data: arrays and vectors (live views) become tuples."""
    if isinstance(value, str) or not hasattr(value, "__len__") or isinstance(value, bpy.types.ID):
        return value
    return tuple(value)


class StateGuard:
    """The one way the add-on changes Blender state it must put back: every change goes through
    this object, which records the old value first; :meth:`restore` (or leaving the ``with``
    block) undoes everything in reverse order, on success, error and cancel alike.

    - :meth:`snapshot` records every writable property of a struct (recursively through nested
      pointers such as ``render.image_settings``) for changes made to it directly afterwards
      (``apply_bake_settings``); the values that differ are written back, twice if needed since an
      enum may be refused until another property is back (e.g. ``color_depth`` vs ``file_format``).
    - :meth:`set` / :meth:`hide` change one property and record its old value. With
      ``tolerate=True`` a write Blender refuses (e.g. linked library data) is listed in
      :attr:`skipped` instead of raising.
    - :meth:`on_restore` registers any other undo step (remove a temporary camera or folder).

    :meth:`restore` is idempotent and returns (and keeps in :attr:`failed`) the labels of the
    steps that could not be undone (e.g. the object was deleted meanwhile).
    """

    def __init__(self):
        self._undo = []     # (kind, payload, label)
        self.skipped = []   # labels of tolerated writes Blender refused
        self.failed = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.restore()
        return False

    def snapshot(self, struct, label):
        """Record all of ``struct`` (writable, non-ID properties) before changing it directly."""
        self._undo.append(("snapshot", (struct, _snapshot(struct)), label))

    def set(self, struct, ident, value, label=None, tolerate=False):
        """``struct.ident = value``, recording the old value. Returns False if a tolerated write
        was refused."""
        label = label or f"{getattr(struct, 'name', type(struct).__name__)}.{ident}"
        old = _plain(getattr(struct, ident))
        if old == _plain(value):
            return True
        try:
            setattr(struct, ident, value)
        except (AttributeError, TypeError, ValueError, RuntimeError):
            if not tolerate:
                raise
            self.skipped.append(label)
            return False
        self._undo.append(("set", (struct, ident, old), label))
        return True

    def hide(self, ob, view_layer, value, tolerate=False):
        """``ob.hide_set(value)`` in ``view_layer`` (the eye), recording the old state."""
        label = f"object[{ob.name}].hide"
        old = ob.hide_get(view_layer=view_layer)
        if old == value:
            return True
        try:
            ob.hide_set(value, view_layer=view_layer)
        except RuntimeError:
            if not tolerate:
                raise
            self.skipped.append(label)
            return False
        self._undo.append(("call", lambda: ob.hide_set(old, view_layer=view_layer), label))
        return True

    def on_restore(self, fn, label):
        """Call ``fn()`` when restoring (in reverse order with the other steps)."""
        self._undo.append(("call", fn, label))

    def restore(self):
        """Undo every recorded change, newest first; returns the labels that failed."""
        failed, retry = [], []
        undo, self._undo = self._undo, []
        for kind, payload, label in reversed(undo):
            try:
                if kind == "set":
                    struct, ident, old = payload
                    setattr(struct, ident, old)
                elif kind == "call":
                    payload()
                else:
                    struct, snap = payload
                    if _restore(struct, snap):
                        retry.append((struct, snap, label))
            except (ReferenceError, AttributeError, TypeError, ValueError, RuntimeError, OSError):
                failed.append(label)
        for struct, snap, label in retry:
            failed += [label + "." + f for f in _restore(struct, snap)]
        self.failed += failed
        return failed


def apply_bake_settings(scene, view_layer, settings, log=print):
    """Override the render settings for panorama renders of a probe bake (see DESIGN.md §6) and
    set the Cycles device per Render Device (:func:`apply_render_device`, which logs through
    ``log`` why a GPU asked for is not used). Returns the label of the device that renders.

    ``settings`` is a :class:`bake_core.BakeSettings`. Everything written here is captured by a
    :class:`StateGuard` (:meth:`StateGuard.snapshot` of ``render``, ``cycles`` and
    ``view_layer``) made before the call. Raises :class:`BakeError` (nothing changed) without Cycles.
    """
    c = require_cycles(scene)
    r = scene.render
    r.engine = 'CYCLES'
    r.resolution_x = settings.panorama_resolution
    r.resolution_y = settings.panorama_resolution // 2
    r.resolution_percentage = 100
    r.pixel_aspect_x = 1.0
    r.pixel_aspect_y = 1.0
    r.use_border = False
    r.film_transparent = False  # a transparent film would drop the sky from the RGB channels
    r.use_compositing = False
    r.use_sequencer = False
    r.use_motion_blur = False
    r.use_multiview = False
    r.use_single_layer = True
    r.use_persistent_data = settings.persistent_data
    r.use_file_extension = True
    im = r.image_settings
    im.file_format = 'OPEN_EXR'
    im.color_mode = 'RGB'
    im.color_depth = '32'
    im.exr_codec = 'NONE'  # lossless either way; uncompressed is fastest to write and read
    compat.set_existing(im, use_zbuffer=False)  # removed in Blender 4.x
    im.use_preview = False

    c.samples = settings.samples
    c.use_denoising = False  # Debian's Blender has no OpenImageDenoise; a denoiser also biases
    c.use_adaptive_sampling = False  # the error should not depend on the image content
    c.use_layer_samples = 'USE'
    c.max_bounces = settings.max_bounces
    c.diffuse_bounces = settings.max_bounces
    c.glossy_bounces = settings.max_bounces
    c.sample_clamp_direct = settings.clamp_direct
    c.sample_clamp_indirect = settings.clamp_indirect
    c.pixel_filter_type = settings.pixel_filter
    c.filter_width = settings.filter_width
    c.film_exposure = 1.0  # radiance in the units Cycles renders in
    c.seed = settings.seed
    c.use_animated_seed = False
    view_layer.samples = 0  # 0 = use the scene's sample count
    return apply_render_device(scene, settings.render_device, log)


# ------------------------------------------------------------------ the render device
def _cpu_label(scene) -> str:
    # render.threads reads the count Cycles uses, also with Threads 'Auto-Detect'.
    n = scene.render.threads
    return f"CPU ({n} thread{'' if n == 1 else 's'})"


_GPU_LIST = [float("-inf"), None]      # (time.monotonic() of the listing, its result)


def _gpu_devices(max_age: float = 0.0):
    """compat.cycles_gpu_devices of the Preferences, listed again when the last listing is older than
    ``max_age`` seconds (the panel redraws often; listing makes Cycles probe its devices)."""
    now = time.monotonic()
    if _GPU_LIST[1] is None or now - _GPU_LIST[0] > max_age:
        _GPU_LIST[:] = [now, compat.cycles_gpu_devices(compat.cycles_preferences())]
    return _GPU_LIST[1]


def _device_plan(scene, render_device, max_age: float = 0.0):
    """``(value for scene.cycles.device or None to leave it, label, why no GPU or None)`` for the
    Render Device setting ``render_device`` ('SCENE', 'CPU', 'GPU'); changes nothing."""
    cycles = require_cycles(scene)
    wanted = cycles.device if render_device == 'SCENE' else render_device
    setting = None if render_device == 'SCENE' else wanted
    if wanted != 'GPU':
        return setting, _cpu_label(scene), None
    kind, names, with_cpu = _gpu_devices(max_age)
    if names:
        return setting, f"GPU: {', '.join(names)} ({kind}{' + CPU' if with_cpu else ''})", None
    if kind == 'NONE':
        why = "Preferences > System > Cycles Render Devices names no compute device type (None)"
    else:
        why = f"no {kind} device is found and enabled in Preferences > System > Cycles Render Devices"
    # 'SCENE': Cycles itself renders a GPU scene on the CPU when it has no GPU; the label says so.
    return ('CPU' if setting else None), f"GPU: none available, {_cpu_label(scene)}", why


def device_label(scene, render_device='SCENE', max_age: float = 0.0) -> str:
    """What renders the panoramas of ``scene`` with Render Device ``render_device``, as a short label
    ("CPU (2 threads)", "GPU: NVIDIA ... (OPTIX)", "GPU: none available, CPU (2 threads)"); the
    default 'SCENE' says what renders now (after :func:`apply_render_device`: what the bake uses).
    Changes no scene setting (listing the devices refreshes the Preferences' device list, as
    Cycles' own panels do); ``max_age`` > 0 reuses a listing that recent (the panel's redraws)."""
    return _device_plan(scene, render_device, max_age)[1]


def apply_render_device(scene, render_device, log=print) -> str:
    """Set ``scene.cycles.device`` per Render Device (the caller's :class:`StateGuard` snapshot of
    ``scene.cycles`` restores it) and return :func:`device_label`'s label. A GPU asked for (or set in
    the scene) that no device of the Preferences provides renders on the CPU: one line through
    ``log`` says why, nothing fails."""
    value, label, why = _device_plan(scene, render_device)
    if value is not None:
        scene.cycles.device = value
    if why is not None:
        asked = "Render Device GPU" if render_device == 'GPU' else "the scene's Device GPU Compute"
        log(f"Schnee: {asked}: no GPU available ({why}); the probes render on the {_cpu_label(scene)}")
    return label


# Modifiers whose viewport level differs from the render level.
_LEVEL_MODIFIERS = {'SUBSURF', 'MULTIRES'}


class RenderEvaluation:
    """``with RenderEvaluation(scene, view_layer, keep=...) as depsgraph:`` the evaluated depsgraph
    with the viewport made to match the render: what Cycles renders is what placement sees.

    Blender 3.4's Python API offers only the viewport depsgraph, which drops objects and
    collections hidden in the viewport (monitor icon, or the eye of an object) and evaluates
    modifiers with their viewport switch and level. For the duration of the block, every collection
    and object of the scene gets ``hide_viewport = hide_render``, render-visible objects are
    un-hidden (eye), each modifier gets ``show_viewport = show_render`` and subdivision/multires
    ``levels = render_levels``. Everything changed is recorded first and put back on exit (success
    or error), and the depsgraph is re-evaluated. Objects and collections named in ``keep`` are
    left alone (the probe volumes, read before the block).
    """

    def __init__(self, scene, view_layer, keep=frozenset()):
        self.scene = scene
        self.view_layer = view_layer
        self.keep = frozenset(keep)
        self.failed = []
        self._state = StateGuard()

    @property
    def skipped(self):
        """Labels of the overrides Blender refused (linked library data); those stay as they are."""
        return list(self._state.skipped)

    def __enter__(self):
        o, keep = self._state, self.keep
        try:
            for coll in self.scene.collection.children_recursive:
                if coll.name not in keep:
                    o.set(coll, "hide_viewport", coll.hide_render, f"collection[{coll.name}].hide_viewport",
                          tolerate=True)
            in_layer = set(self.view_layer.objects.keys())
            for ob in self.scene.objects:
                if ob.name in keep:
                    continue
                o.set(ob, "hide_viewport", ob.hide_render, f"object[{ob.name}].hide_viewport", tolerate=True)
                if ob.name in in_layer and not ob.hide_render:
                    o.hide(ob, self.view_layer, False, tolerate=True)
                for mod in ob.modifiers:
                    label = f"object[{ob.name}].modifiers[{mod.name}]"
                    o.set(mod, "show_viewport", mod.show_render, label + ".show_viewport", tolerate=True)
                    if mod.type in _LEVEL_MODIFIERS:
                        o.set(mod, "levels", mod.render_levels, label + ".levels", tolerate=True)
        except BaseException:
            self.failed = o.restore()
            raise
        depsgraph = bpy.context.evaluated_depsgraph_get()
        depsgraph.update()
        return depsgraph

    def __exit__(self, *exc):
        self.failed = self._state.restore()
        bpy.context.evaluated_depsgraph_get().update()
        return False
