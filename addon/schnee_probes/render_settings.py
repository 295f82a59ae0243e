"""Save, override and restore the scene state a bake touches.

A bake changes render, Cycles, image and view-layer settings, the scene camera and some objects'
visibility flags. :class:`SceneState` records every writable property of those structs (recursively
through nested pointers such as ``render.image_settings``) before anything changes, and puts back
the values that differ afterwards, on success, error and cancel alike.
"""
import bpy

from . import compat

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


class SceneState:
    """Everything a bake may change on ``scene``, captured at construction."""

    def __init__(self, scene, view_layer, objects=()):
        self.scene = scene
        self.view_layer = view_layer
        self.render = _snapshot(scene.render)
        cycles = compat.cycles_settings(scene)  # saved/restored only where Cycles' settings exist
        self.cycles = _snapshot(cycles) if cycles is not None else {}
        self.view_layer_state = _snapshot(view_layer)
        self.camera = scene.camera
        self.frame = (scene.frame_current, scene.frame_subframe)
        self.objects = {}
        for ob in objects:
            self._remember_object(ob)

    def _remember_object(self, ob):
        flags = {"hide_render": ob.hide_render}
        if compat.has_visible_camera(ob):
            flags["visible_camera"] = ob.visible_camera
        self.objects[ob.name] = (ob, flags)

    def remember_object(self, ob):
        """Record ``ob``'s visibility flags before the bake changes them (idempotent)."""
        if ob.name not in self.objects:
            self._remember_object(ob)

    def restore(self):
        """Put everything back. Returns a list of properties that could not be restored."""
        scene = self.scene
        failed = []
        # Twice: an enum may be refused until another property is back (e.g. color_depth vs format).
        for _ in range(2):
            failed = ["render." + f for f in _restore(scene.render, self.render)]
            if self.cycles:
                failed += ["cycles." + f for f in _restore(compat.cycles_settings(scene), self.cycles)]
            failed += ["view_layer." + f for f in _restore(self.view_layer, self.view_layer_state)]
            if not failed:
                break
        if scene.camera != self.camera:
            scene.camera = self.camera
        if (scene.frame_current, scene.frame_subframe) != self.frame:
            scene.frame_set(self.frame[0], subframe=self.frame[1])
        for ob, flags in self.objects.values():
            try:
                for ident, value in flags.items():
                    if getattr(ob, ident) != value:
                        setattr(ob, ident, value)
            except ReferenceError:
                pass  # the object was deleted meanwhile; nothing to restore
        return failed


def apply_bake_settings(scene, view_layer, settings):
    """Override the render settings for panorama renders of a probe bake (see DESIGN.md §6).

    ``settings`` is a :class:`bake_core.BakeSettings`. Everything written here is captured by a
    :class:`SceneState` made before the call.
    """
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

    c = scene.cycles
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


class _Overrides:
    """Attribute writes recorded with their old values, undone in reverse order by :meth:`restore`
    (the same contract as :class:`SceneState`: record first, change, put back what differs)."""

    def __init__(self):
        self._undo = []  # (setter, old value, label)
        self.skipped = []  # labels of writes Blender refused (e.g. linked library data)

    def set(self, struct, ident, value, label):
        old = getattr(struct, ident)
        if old != value:
            try:
                setattr(struct, ident, value)
            except (AttributeError, TypeError, ValueError, RuntimeError):
                self.skipped.append(label)
                return
            self._undo.append((lambda v, s=struct, i=ident: setattr(s, i, v), old, label))

    def hide(self, ob, view_layer, value):
        old = ob.hide_get(view_layer=view_layer)
        if old != value:
            try:
                ob.hide_set(value, view_layer=view_layer)
            except RuntimeError:
                self.skipped.append(f"object[{ob.name}].hide")
                return
            self._undo.append((lambda v, o=ob: o.hide_set(v, view_layer=view_layer), old,
                               f"object[{ob.name}].hide"))

    def restore(self):
        """Undo every write; returns the labels of those that failed."""
        failed = []
        for setter, old, label in reversed(self._undo):
            try:
                setter(old)
            except (ReferenceError, AttributeError, TypeError, ValueError, RuntimeError):
                failed.append(label)
        self._undo.clear()
        return failed


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
        self._overrides = _Overrides()

    @property
    def skipped(self):
        """Labels of the overrides Blender refused (linked library data); those stay as they are."""
        return list(self._overrides.skipped)

    def __enter__(self):
        o, keep = self._overrides, self.keep
        try:
            for coll in self.scene.collection.children_recursive:
                if coll.name not in keep:
                    o.set(coll, "hide_viewport", coll.hide_render, f"collection[{coll.name}].hide_viewport")
            in_layer = set(self.view_layer.objects.keys())
            for ob in self.scene.objects:
                if ob.name in keep:
                    continue
                o.set(ob, "hide_viewport", ob.hide_render, f"object[{ob.name}].hide_viewport")
                if ob.name in in_layer and not ob.hide_render:
                    o.hide(ob, self.view_layer, False)
                for mod in ob.modifiers:
                    label = f"object[{ob.name}].modifiers[{mod.name}]"
                    o.set(mod, "show_viewport", mod.show_render, label + ".show_viewport")
                    if mod.type in _LEVEL_MODIFIERS:
                        o.set(mod, "levels", mod.render_levels, label + ".levels")
        except BaseException:
            self.failed = o.restore()
            raise
        depsgraph = bpy.context.evaluated_depsgraph_get()
        depsgraph.update()
        return depsgraph

    def __exit__(self, *exc):
        self.failed = self._overrides.restore()
        bpy.context.evaluated_depsgraph_get().update()
        return False
