"""Bake settings, stored on the scene as ``Scene.schnee_probes``.

Property names equal the fields of :class:`bake_core.BakeSettings` and the ``bake.py`` options.
Defaults and their time/error trade are documented in docs/user-guide.md (figures measured with
bench/sweep/run.py, report bench/results/sweep.md).
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from .bake_core import DEFAULT_OUTPUT


class SchneeProbeSettings(bpy.types.PropertyGroup):
    """Settings of Bake SH in Volumes / Bake SH at Cursor, and what the last bake produced."""

    # The five documented parameters (DESIGN.md §6).
    volume_collection: StringProperty(
        name="Probe Volume Collection", default="ProbeVolumes",
        description="Collection of closed mesh objects; probes fill their union. "
                    "Its objects are hidden from the probe renders and left out of the glTF export")
    min_cell_size: FloatProperty(
        name="Min Cell Size (m)", default=0.5, min=0.01, soft_max=4.0, unit='LENGTH',
        description="Smallest octree cell, used near scene geometry; also the spacing of the "
                    "occupancy grid written to the .shprobe")
    max_cell_size: FloatProperty(
        name="Max Cell Size (m)", default=16.0, min=0.01, soft_max=64.0, unit='LENGTH',
        description="Largest octree cell, used in open space away from geometry")
    panorama_resolution: IntProperty(
        name="Panorama Resolution", default=128, min=8, max=4096, step=2,
        description="Width of each per-probe equirectangular render; height = width / 2")
    max_band: IntProperty(
        name="Max SH Band (L)", default=2, min=0, max=4,
        description="Highest SH band; L=2 gives 9 coefficients (the .shprobe v1 format holds L<=2)")

    # Settings that trade time against error.
    samples: IntProperty(
        name="Samples", default=32, min=1, soft_max=4096,
        description="Cycles samples per panorama pixel: render time grows linearly, noise falls "
                    "as 1/sqrt(samples) (measured: 32 is within noise of 64-128 indoors; raise it "
                    "for skies with a small, very bright sun)")
    max_bounces: IntProperty(
        name="Bounces", default=32, min=0, max=64,
        description="Light bounces (total, diffuse and glossy): fewer is faster but darker indoors "
                    "(light missing ≈ albedo^bounces; bright room: 8 lose 13 %, 16 lose 2.8 %, "
                    "24 lose 0.6 %, 32 are within noise); extra bounces cost little, outdoors 4 are enough")
    clamp_direct: FloatProperty(
        name="Clamp Direct", default=0.0, min=0.0,
        description="Clamp of direct-light samples (0 = off); clamping trades fireflies for bias")
    clamp_indirect: FloatProperty(
        name="Clamp Indirect", default=10.0, min=0.0,
        description="Clamp of indirect-light samples (0 = off; 10 is Cycles' default)")
    pixel_filter: EnumProperty(
        name="Pixel Filter", default='BOX',
        items=(('BOX', "Box", "Each sample counts only for its own pixel: the panorama pixel is the "
                "exact solid-angle average the projection assumes"),
               ('GAUSSIAN', "Gaussian", "Gaussian pixel filter"),
               ('BLACKMAN_HARRIS', "Blackman-Harris", "Cycles' default filter; blurs across "
                "rows of different solid angle")),
        description="Cycles pixel filter for the panoramas")
    filter_width: FloatProperty(
        name="Filter Width (px)", default=1.0, min=0.01, max=10.0,
        description="Pixel filter width; 1 px box = no blur between pixels")
    lights_visible: BoolProperty(
        name="Lamps Seen by Probes", default=True,
        description="Lamp objects are seen directly by the probe cameras, so a lamp's own emission "
                    "counts in the probes' light (as an emissive surface would); off hides lamps "
                    "from the probe cameras (they still light the scene)")
    per_volume_files: BoolProperty(
        name="One File per Volume", default=False,
        description="Write sh_coeffs/<volume name>.shprobe for each volume (placed separately) "
                    "instead of one probes.shprobe for their union")
    persistent_data: BoolProperty(
        name="Persistent Data", default=True,
        description="Keep the scene in Cycles between probe renders, so a probe costs path "
                    "tracing and not scene sync")
    seed: IntProperty(name="Seed", default=0, min=0, description="Cycles noise seed")
    default_sh_scale: FloatProperty(
        name="Default SH Scale", default=1.0, min=0.0,
        description="SH scale written to the .shprobe header (engine default per probe)")
    default_ambient: FloatProperty(
        name="Default Ambient", default=0.1, min=0.0,
        description="Ambient term written to the .shprobe header")
    output_path: StringProperty(
        name="Output", default=DEFAULT_OUTPUT, subtype='FILE_PATH',
        description="The .shprobe written by Bake SH in Volumes ('//' = folder of the saved .blend); "
                    "per-volume files and the cursor bake's debug_probe.txt go in the same folder")

    # What the last bake produced (shown in the panel; saved with the .blend).
    last_probe_count: IntProperty(name="Probes", default=0)
    last_seconds: FloatProperty(name="Time (s)", default=0.0)
    last_files: StringProperty(name="Files", default="")
    last_message: StringProperty(name="Last Bake", default="")


classes = (SchneeProbeSettings,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.schnee_probes = PointerProperty(type=SchneeProbeSettings)


def unregister():
    del bpy.types.Scene.schnee_probes
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
