"""Every bake setting, declared once.

:data:`SETTINGS` is the single declaration of each bake setting: its name, type, default, limits or
choices, help text, UI label, where the panel draws it, and the text of the user guide's settings
table. Everything else is derived from it:

- :class:`BakeSettings` (the dataclass the bake runs with) and :meth:`BakeSettings.validate`,
- the ``Scene.schnee_probes`` PropertyGroup (``properties.py``) and the panel/dialog drawing
  (``properties.draw_settings``),
- ``bake.py``'s command-line options (:func:`add_arguments`),
- the settings table in docs/user-guide.md (``scripts/gen_settings_table.py``, checked by
  ``tests/python/test_settings.py``).

Adding a setting = one :class:`Setting` entry here (plus the code that uses it) and regenerating the
guide's table. This module needs no ``bpy``: plain Python (tests, the doc generator) imports it.
"""
from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Optional, Tuple

DEFAULT_OUTPUT = "//sh_coeffs/probes.shprobe"


class BakeError(RuntimeError):
    """A bake that cannot start or continue; the message is meant for the user as is."""


@dataclass(frozen=True)
class Setting:
    """One bake setting.

    ``kind``: "bool", "int", "float", "enum", "str" (a collection name) or "path" (a file path).
    ``minimum``/``maximum``: hard limits, the same in the property, ``validate`` and the guide
    (``min_exclusive``: the value must be strictly greater). ``even``: ints must be even.
    ``soft_max``: the UI slider's end only. ``choices``: (identifier, label, description) per item.
    ``ui``: where the panel/dialog draws it: "all", "volumes" (only for Bake SH in Volumes) or
    None (scripts, ``bake.py`` and the property only). Settings with the same ``ui_row`` share a row.
    ``doc``: the guide's "What it trades" text (default: ``help``).
    """
    name: str
    kind: str
    default: Any
    label: str
    help: str
    doc: str = ""
    minimum: Optional[float] = None
    maximum: Optional[float] = None
    min_exclusive: bool = False
    even: bool = False
    soft_max: Optional[float] = None
    choices: Tuple[Tuple[str, str, str], ...] = ()
    unit: str = ""            # Blender property unit ('LENGTH') or ""
    suffix: str = ""          # unit text for the guide and bake.py's help ("m", "px")
    ui: Optional[str] = "all"
    ui_row: str = ""
    ui_text: Optional[str] = None
    option: str = ""          # bake.py option; default "--" + name with '-' for '_'

    @property
    def cli(self) -> str:
        return self.option or "--" + self.name.replace("_", "-")

    @property
    def choice_ids(self) -> Tuple[str, ...]:
        return tuple(c[0] for c in self.choices)

    def format_value(self, value) -> str:
        """A value as the guide and messages show it."""
        if self.kind == "bool":
            return "on" if value else "off"
        if self.kind == "enum":
            return next((c[1] for c in self.choices if c[0] == value), str(value))
        if self.kind in ("str", "path"):
            return f"`{value}`"
        return f"{value:g}" if isinstance(value, float) else str(value)

    def limits_text(self) -> str:
        """The limits in words (the guide's Limits column)."""
        if self.kind == "enum":
            return ", ".join(c[1] for c in self.choices)
        if self.kind == "bool":
            return "on / off"
        if self.kind in ("str", "path"):
            return "not empty" + ("; must end in `.shprobe`" if self.kind == "path" else "")
        parts = []
        if self.minimum is not None:
            parts.append((">" if self.min_exclusive else "≥") + f" {self.minimum:g}")
        if self.maximum is not None:
            parts.append(f"≤ {self.maximum:g}")
        if self.even:
            parts.append("even")
        return ", ".join(parts) or "any"

    def check(self, value) -> Optional[str]:
        """None if ``value`` is allowed, else why not (one sentence naming the setting)."""
        what = f"{self.label} ({self.cli})"
        if self.kind == "bool":
            return None if isinstance(value, bool) else f"{what} must be on or off (got {value!r})"
        if self.kind == "enum":
            if value not in self.choice_ids:
                return f"{what} must be one of {', '.join(self.choice_ids)} (got {value!r})"
            return None
        if self.kind in ("str", "path"):
            if not isinstance(value, str) or not value:
                return f"{what} is empty"
            if self.kind == "path" and not value.endswith(".shprobe"):
                return f"{what} must name a .shprobe file (got '{value}'): the bake writes only .shprobe files"
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return f"{what} must be a number (got {value!r})"
        if self.kind == "int" and not float(value).is_integer():
            return f"{what} must be a whole number (got {value})"
        if not math.isfinite(value):
            return f"{what} must be finite (got {value})"
        lo, hi = self.minimum, self.maximum
        if lo is not None and (value <= lo if self.min_exclusive else value < lo):
            return f"{what} must be {'>' if self.min_exclusive else '>='} {lo:g} (got {value:g})"
        if hi is not None and value > hi:
            return f"{what} must be <= {hi:g} (got {value:g})"
        if self.even and int(value) % 2:
            return f"{what} must be even (got {value})"
        return None


PIXEL_FILTER_CHOICES = (
    ('BOX', "Box", "Each sample counts only for its own pixel: the panorama pixel is the exact "
                   "solid-angle average the projection assumes"),
    ('GAUSSIAN', "Gaussian", "Gaussian pixel filter"),
    ('BLACKMAN_HARRIS', "Blackman-Harris", "Cycles' default filter; blurs across rows of "
                                           "different solid angle"),
)

SETTINGS: Tuple[Setting, ...] = (
    # The five documented parameters (DESIGN.md §6).
    Setting("volume_collection", "str", "ProbeVolumes", "Probe Volume Collection",
            "Collection of closed mesh objects; probes fill their union. Its objects are hidden "
            "from the probe renders and left out of the glTF export",
            doc="Collection of closed meshes; probes fill their union.", ui="volumes"),
    Setting("min_cell_size", "float", 0.5, "Min Cell Size (m)",
            "Smallest octree cell: where the light changes (Adaptive) or near scene geometry "
            "(Geometry Octree); also the lattice / grid spacing written to the .shprobe",
            doc="Smallest octree cell: Adaptive refines down to it where the light changes, Geometry "
                "Octree near geometry; also the `.shprobe` lattice / grid spacing. Halving it gives up "
                "to 8× the probes where cells reach it (Geometry Octree: 8× the bake time).",
            minimum=0.01, soft_max=4.0, unit='LENGTH', suffix="m"),
    Setting("max_cell_size", "float", 16.0, "Max Cell Size (m)",
            "Largest octree cell: Adaptive's first layer, Geometry Octree's cells away from geometry",
            doc="Largest cell: the first layer Adaptive bakes and refines (wherever the light is "
                "smooth it stays); Geometry Octree's cells in open space. At least Min Cell Size; no "
                "upper limit (16 m is only the default), so 20 / 40 m cells are valid.",
            minimum=0.01, soft_max=64.0, unit='LENGTH', suffix="m", ui="volumes"),
    Setting("placement", "enum", 'ADAPTIVE', "Placement",
            "Where the probes go: Adaptive bakes a coarse layer of Max Cell Size and refines, pass by "
            "pass, only where a test probe shows the interpolation is off by more than the Error "
            "Tolerance (writes .shprobe version 3, an octree the engine interpolates continuously); "
            "Geometry Octree refines every cell that touches geometry to Min Cell Size and writes the "
            "dense grid of versions 1/2",
            doc="**Adaptive**: a layer of Max Cell Size cells, then pass by pass a test probe at each "
                "cell's centre and face centres; a cell splits where the light interpolated from its "
                "corners misses a test by more than Error Tolerance (twice the probes' measured noise added in quadrature); "
                "test probes become the finer cells' probes. Writes `.shprobe` version 3 (corner "
                "octree, trilinear, continuous). **Geometry Octree**: the placement before issue 12 "
                "(every cell touching geometry down to Min Cell Size, one probe per leaf, versions "
                "1/2); in a room that is a uniform grid (2458 probes in the bundled room).",
            choices=(('ADAPTIVE', "Adaptive", "Refine where the light's interpolation error is above "
                                              "the tolerance; .shprobe version 3 (octree)"),
                     ('OCTREE', "Geometry Octree", "Refine every cell touching geometry to Min Cell "
                                                   "Size; .shprobe version 1/2 dense grid")),
            ui="volumes"),
    Setting("error_tolerance", "float", 0.03, "Error Tolerance",
            "Adaptive placement: relative irradiance error (RMS over directions) a cell's "
            "interpolation may have at its test points before it splits; smaller = more probes",
            doc="Adaptive only: the relative irradiance error (RMS over directions and RGB) a cell's "
                "interpolation may show at its test points before it splits, on top of twice the "
                "measured Monte-Carlo noise. Smaller = more probes near light changes; it does not add "
                "probes where the light is smooth. Bundled room at the add-on's defaults "
                "(bench/results/placement.md): {num:room_defaults_probes} probes, {num:room_defaults_points} points "
                "rendered, {num:room_defaults_error_mean} % mean error between probes (floor 1.0 %), "
                "{num:room_defaults_minutes} min on 2 cores; at 4 spp {num:room_4spp_error_mean} % in "
                "{num:room_4spp_minutes} min. The "
                "noise is added in quadrature (sqrt(tolerance² + (2σ)²)), so the tolerance holds at "
                "low Samples too; with the sum tolerance + 2σ used before, 0.03 gave 2.2 % and 0.02 "
                "2.05 %. At reduced quality (64×32 px, 16 spp, that rule) 0.05 / 0.03 gave 712 / 1008 "
                "probes, 1152 / 1547 points and 4.2 / 2.5 %.",
            minimum=0.0, min_exclusive=True, maximum=1.0, ui="volumes"),
    Setting("refinement_tests", "enum", 'CENTRE_FACES', "Refinement Tests",
            "Adaptive placement: where a cell is tested before it may split: its centre and its six "
            "face centres, or its centre only (a draft: far fewer renders, light changes near the "
            "cells' faces missed)",
            doc="Adaptive only: the test points of a cell. **Centre and faces** (default): the centre "
                "and the six face centres. **Centre**: one test at the cell's centre (a split cell's "
                "face centres are baked as its children's corners anyway), a draft: in the bundled "
                "room (bench/results/placement.md, 64×32 px, 16 spp) 560 instead of 1982 points "
                "rendered, but 10.2 % instead of 3.3 % error between probes — in a room the light "
                "changes most near the walls, where the face centres are.",
            choices=(('CENTRE_FACES', "Centre and faces", "Test each cell at its centre and its six face "
                                                          "centres"),
                     ('CENTRE', "Centre (draft)", "Test each cell at its centre only: fewer renders, "
                                                  "larger error")),
            ui="volumes"),
    Setting("file_version", "enum", 'V3', "File Version",
            "Adaptive placement: version 3 (the octree, interpolated continuously) or version 1 (the "
            "same light resampled onto a dense grid of Min Cell Size, for engines that read only "
            "the first format)",
            doc="Adaptive only. **3**: the corner octree as baked. **1 (dense grid)**: the octree's "
                "field sampled at the centre of every Min Cell Size cell of the volumes, written as "
                "version 1 (version 2 above L = 2), for engines that read only the seed's format; "
                "larger file, light constant per cell.",
            choices=(('V3', "3 (octree)", "Version 3: the corner octree, interpolated continuously"),
                     ('V1', "1 (dense grid)", "Version 1: resampled onto a dense grid of Min Cell Size")),
            ui="volumes"),
    Setting("probe_representation", "enum", 'SH', "Probe Representation",
            "Adaptive placement, File Version 3: what each probe record holds: the SH coefficients, "
            "or the ambient cube fitted to them (6 irradiance colours, float32 or half floats)",
            doc="Adaptive only, File Version 3 (issue 16): **SH** writes the radiance SH; **Ambient "
                "cube** writes the 6-colour irradiance cube fitted to it (least squares, "
                "docs/ambient-cube.md), float32 or binary16 (half the size, 0.03 % rounding). The "
                "glTF entry says which (`representation`, `storage`).",
            choices=(('SH', "SH", "Radiance SH coefficients"),
                     ('CUBE_FLOAT', "Ambient cube (float)", "6 irradiance colours per probe, float32"),
                     ('CUBE_HALF', "Ambient cube (half)", "6 irradiance colours per probe, binary16")),
            ui="volumes"),
    Setting("panorama_resolution", "int", 128, "Panorama Resolution",
            "Width of each per-probe equirectangular render; height = width / 2",
            doc="Panorama width (height = width/2). Time grows with the pixel count (×4 per "
                "doubling); SH band 2 needs little resolution, see below. The band also sets a "
                "minimum (2(L+1) samples per axis: 6×6 for L = 2).",
            minimum=4, maximum=4096, even=True, suffix="px"),
    Setting("max_band", "int", 2, "Max SH Band (L)",
            "Highest SH band; L=2 gives 9 coefficients (the .shprobe v1 format holds L<=2)",
            doc="The `.shprobe` v1 format holds L ≤ 2 (9 coefficients); L 3–4 write version 2, "
                "which then also stores each probe's position and validity (1 − the placement's "
                "back-face ratio).",
            minimum=0, maximum=4),
    # What the bake does to the final probes before writing them (postprocess.py, issue 31).
    Setting("dilate_invalid", "bool", False, "Dilate Invalid Probes",
            "Adaptive placement: a probe inside geometry (never rendered, left out of the interpolation) "
            "gets the validity-weighted mean of the valid probes of its cells and is then interpolated "
            "like the others (its validity becomes 0.01); off: it stays out of the interpolation",
            doc="Adaptive only: a probe the solid test put inside geometry (validity 0: never rendered, "
                "left out of the interpolation) gets the mean of the valid probes of the cells it is a "
                "corner of, weighted by validity / distance², and validity 0.01, so readers interpolate "
                "with it as APV and EEVEE do with their dilated probes. Off by default: measured "
                "(bench/results/postprocess.md) it changes no value at the 64 points of the room and "
                "the courtyard nor on the 5 test spheres (none lies in a cell with an invalid "
                "corner), and at 28 points chosen in such cells of the room it raised the median "
                "error from 37 to 58 % (next to the emissive ceiling panel); the interpolation "
                "already renormalises over a cell's valid corners. Applied when the file is written, "
                "so it is not part of the journal's fingerprint: a resumed bake with the other value "
                "reuses the rendered probes.",
            ui="volumes"),
    Setting("sh_window", "enum", 'NONE', "SH Windowing",
            "Deringing: scale each probe's SH bands by a window before writing (Laplacian: Sloan's "
            "deringing, Sinc⁴: Filament's), trading directional detail for less ringing",
            doc="Deringing (docs/sh.md *Ringing windows*): each probe's band l scaled by the window's "
                "factor before the file is written. **Laplacian** 1/(1 + λ l²(l+1)²) (Sloan 2017), "
                "**Sinc⁴** (sin x / x)⁴, x = πl/w (Filament). None by default: every fixed window raised the error between probes "
                "(bench/results/postprocess.md; room 1.77 % → 2.06 % at λ 0.002, 3.43 % at 0.01, 2.88 % "
                "at w 12; test spheres per pixel 7.2 → 7.4 / 8.8 / 8.1 %); the automatic strength "
                "changes only probes whose irradiance goes negative (none in those bakes): use it where "
                "probes see a small bright baked source. Like dilation, applied at write time and not "
                "part of the journal's fingerprint.",
            choices=(('NONE', "None", "Write the probes' SH as baked"),
                     ('LAPLACIAN', "Laplacian", "Band l scaled by 1/(1 + strength · l²(l+1)²)"),
                     ('SINC4', "Sinc⁴", "Band l scaled by sinc⁴(πl / strength), 0 from band strength on")),
            ui="volumes", ui_row="window"),
    Setting("sh_window_strength", "float", 0.0, "SH Window Strength",
            "SH Windowing's strength: Laplacian λ, Sinc⁴ cutoff band w; 0 = per probe, the weakest "
            "window that makes its irradiance non-negative in every direction",
            doc="Laplacian: λ; Sinc⁴: the cutoff band w (bands ≥ w are removed: w ≤ L removes bands). "
                "0 = automatic per probe: the weakest window whose irradiance is ≥ 0 in every direction "
                "(a probe that is nowhere negative is left as it is).",
            minimum=0.0, soft_max=10.0, ui="volumes", ui_row="window", ui_text="Strength"),
    # Settings that trade time against error.
    Setting("samples", "int", 8, "Samples",
            "Cycles samples per panorama pixel: render time grows linearly, noise falls as "
            "1/sqrt(samples) (measured: 8 keep a probe within 1 % indoors, and a moving object's "
            "error is the interpolation's between probes; the sky and lamps seen directly are exact "
            "at any samples, so a small bright sun needs no more). Adaptive placement spends them "
            "where a decision needs them: every point first gets two rounds of a quarter of them, "
            "a probe more only while its noise is above half of Error Tolerance, a test point "
            "more only where its split is unclear, no point more than Samples",
            doc="Cycles samples per pixel. Time is linear in it, noise falls as 1/√samples. With "
                "Adaptive placement Samples sets the rounds (docs/placement.md step 3): every point "
                "first gets two rounds of Samples/4 with different seeds (its noise measured), a probe "
                "then one more round only while its noise is above Error Tolerance/2, a test point only "
                "where its split decision is unclear given its noise; no point gets more than "
                "Samples. In the "
                "bright room at 32 bounces 8 / 16 / 32 / 64 / 128 spp give 0.81 / 0.57 / 0.42 / "
                "0.33 / 0.28 % per probe (table below); between the probes of the bundled room the "
                "default 8 spp bake is {num:room_defaults_error_mean} % off, 32 spp take 4× as long for the 0.4 points per "
                "probe (*Placement: measured*). The sky and the lamps a probe sees directly are "
                "added exactly (docs/direct-light.md), so a small bright sun in the sky or a Sun "
                "lamp needs no more samples (sun scenes of the table); a sky seen through glass "
                "is still path traced.",
            minimum=1, soft_max=4096),
    Setting("max_bounces", "int", 32, "Bounces",
            "Light bounces (total, diffuse and glossy): fewer is faster but darker indoors (light "
            "missing ≈ albedo^bounces; bright room: 8 lose 13 %, 16 lose 2.8 %, 24 lose 0.6 %, 32 "
            "are within noise); extra bounces cost little, outdoors 4 are enough",
            doc="Total, diffuse and glossy bounces. Light missing ≈ albedo^bounces: in a bright "
                "(albedo 0.8) room 2 / 4 / 8 / 12 / 16 / 24 / 32 bounces give 40 / 27 / 13 / 6.0 / "
                "2.8 / 0.57 / 0.33 % error (64 spp); outdoors 4 are as good as 32. Extra bounces "
                "cost little: only the paths that survive that long pay.",
            minimum=0, maximum=64),
    Setting("clamp_direct", "float", 0.0, "Clamp Direct",
            "Clamp of direct-light samples (0 = off); clamping trades fireflies for bias",
            doc="Clamp on direct samples (0 = off): fewer fireflies, biased low.",
            minimum=0.0, ui_row="clamp"),
    Setting("clamp_indirect", "float", 10.0, "Clamp Indirect",
            "Clamp of indirect-light samples (0 = off; 10 is Cycles' default)",
            doc="Clamp on indirect samples (0 = off; Cycles' default 10): suppresses fireflies "
                "from small bright paths at a small bias.",
            minimum=0.0, ui_row="clamp"),
    Setting("pixel_filter", "enum", 'BOX', "Pixel Filter", "Cycles pixel filter for the panoramas",
            doc="Box 1 px makes each pixel the exact solid-angle average the projection assumes; "
                "Cycles' default Blackman–Harris 1.5 px blurs energy between rows of different "
                "solid angle.",
            choices=PIXEL_FILTER_CHOICES, ui_row="filter", ui_text=""),
    Setting("filter_width", "float", 1.0, "Filter Width (px)",
            "Pixel filter width; 1 px box = no blur between pixels",
            doc="Width of the pixel filter.", minimum=0.01, maximum=10.0, suffix="px",
            ui_row="filter", ui_text="Width"),
    Setting("lights_visible", "bool", True, "Lamps Seen by Probes",
            "The light reaching a probe straight from a baked lamp counts in the probes (Sun, Point, "
            "Spot and Area lamps of constant emission added exactly, shadowed by the scene; others "
            "seen by the probe cameras); off: lamps still light the scene, only their bounced light "
            "is in the probes",
            doc="The light that reaches a probe straight from a baked lamp counts in the probe. Sun, "
                "Point, Spot and Area (spread 180°) lamps of constant emission are added exactly, "
                "shadowed by the render geometry, and hidden from the probe cameras so nothing counts "
                "twice; lamps with node-driven emission or a narrower spread are seen by the probe "
                "cameras (path traced). Off: lamps still light the scene (their bounced light is in "
                "the probes) but their direct light is not. Realtime lamps are never in the probes, "
                "mixed lamps only with their bounced light (docs/direct-light.md)."),
    Setting("sky_sun", "enum", "mixed", "Sky Sun",
            "A compact bright sun in the world (an HDRI's or a Nishita sky's): Mixed splits it off as "
            "a directional light the engine adds with shadow maps (sharp sunbeams; the probes keep "
            "the rest of the sky and the sun's bounced light, sky.exr loses the sun, "
            "sh_coeffs/sun.json records it for the glTF export); Baked keeps it in the probes",
            doc="**Mixed**: a compact bright sun in the world (an HDRI's, a Nishita sky's; criteria and "
                "measured figures in docs/direct-light.md *The sky's sun*) is split off: the probes "
                "see the rest of the sky directly (the sun's bounced light stays in them), `sky.exr` "
                "loses it too, and `sh_coeffs/sun.json` records it, which the glTF export writes as a "
                "mixed directional light (docs/export.md) that the engine shadows per pixel. A sky "
                "without such a sun is baked as it is. **Baked**: the sun stays in the probes, "
                "interpolated across cells (a sunbeam's edge blurs over a cell).",
            choices=(("mixed", "Mixed", "Split the sky's sun off as a directional light the engine "
                                        "shadows; the probes hold the rest of the sky"),
                     ("baked", "Baked", "Keep the sky's sun in the probes")),
            option="--sky-sun"),
    Setting("persistent_data", "bool", True, "Persistent Data",
            "Keep the scene in Cycles between probe renders, so a probe costs path tracing and not "
            "scene sync",
            doc="Keeps the scene in Cycles between probe renders, so a probe costs path tracing, "
                "not scene sync."),
    Setting("render_device", "enum", 'SCENE', "Render Device",
            "What renders the probe panoramas: the scene's Cycles device as it is set, the CPU, or the "
            "GPU devices enabled in Preferences > System > Cycles Render Devices (the CPU when none is "
            "usable: the bake log says why); the scene's setting is restored after the bake",
            doc="**As the scene is set** (default): Render Properties > Device is left as it is (a scene "
                "set to GPU Compute without a usable GPU renders on the CPU, Cycles' own fallback, and "
                "the bake says so). **CPU**: the CPU, whatever the scene says. **GPU**: the compute "
                "device type and the devices enabled in Preferences > System > Cycles Render Devices "
                "(with the CPU too where it is ticked there); with type None, or no device of that "
                "type found and enabled, the bake renders on the CPU and logs one line saying why. "
                "CPU and GPU are set for the bake only and restored after it. The progress line and "
                "the estimate name the device; the estimate before the first probe is this 2-core "
                "CPU's cost model, an upper one on a GPU (see *Rendering on a GPU*).",
            choices=(('SCENE', "As the scene is set", "Render on the scene's Cycles device (Render "
                                                      "Properties > Device), unchanged"),
                     ('CPU', "CPU", "Render on the CPU, whatever the scene's device"),
                     ('GPU', "GPU", "Render on the GPU devices enabled in Preferences > System > Cycles "
                                    "Render Devices; on the CPU when none is usable (the log says why)"))),
    Setting("per_volume_files", "bool", False, "One File per Volume",
            "Write sh_coeffs/<volume name>.shprobe for each volume (placed separately) instead of "
            "one probes.shprobe for their union",
            doc="Writes `sh_coeffs/<volume name>.shprobe` per volume (each placed on its own) "
                "instead of one `probes.shprobe` for their union. Positions shared by volumes are "
                "rendered once.",
            ui="volumes"),
    Setting("capture_sky", "bool", True, "Capture Sky",
            "A volume bake also renders the world alone to sky.exr next to the probe files (the "
            "engine's background, far light and reflections)",
            doc="A volume bake also renders the world alone to `sky.exr` next to the probe files "
                "(see *The sky*).",
            ui="volumes"),
    Setting("sky_resolution", "int", 512, "Sky Resolution",
            "Width of sky.exr; height = width / 2",
            doc="Width of `sky.exr` (height = width/2).",
            minimum=4, maximum=16384, even=True, soft_max=4096, suffix="px", ui="volumes"),
    Setting("probe_limit", "int", 20000, "Confirm Above (probes)",
            "A bake of more probes than this asks for confirmation first (bake.py: needs "
            "--allow-large); 0 = never ask",
            doc="A bake of more probes than this asks for confirmation before the first render "
                "(`bake.py` refuses it, exit 3, unless `--allow-large` is given); 0 = never ask. "
                "20000 probes are about 5 h at the defaults in a closed room (estimate: see "
                "*Before a bake starts*).",
            minimum=0, ui="volumes"),
    Setting("seed", "int", 0, "Seed", "Cycles noise seed", doc="Cycles noise seed.", minimum=0,
            ui=None),
    Setting("default_sh_scale", "float", 1.0, "Default SH Scale",
            "Stored in the .shprobe header's Default SH Scale field (kept for the version 1 layout); "
            "readers, the engine included, ignore it: the engine scales by each probe's own scale "
            "and the material's SH scale",
            doc="Stored in the `.shprobe` header only; readers, the engine included, ignore it "
                "(docs/shprobe-format.md, *What readers use*).", minimum=0.0, ui=None),
    Setting("default_ambient", "float", 0.1, "Default Ambient",
            "Stored in the .shprobe header's Default Ambient field and as every probe's ambient (kept "
            "for the version 1 layout); readers, the engine included, ignore both: the engine's "
            "ambient term is the material's",
            doc="Stored in the `.shprobe` header and as every probe's ambient; readers, the engine "
                "included, ignore both (docs/shprobe-format.md, *What readers use*).", minimum=0.0, ui=None),
    Setting("output_path", "path", DEFAULT_OUTPUT, "Output",
            "The .shprobe written by Bake SH in Volumes ('//' = folder of the saved .blend); "
            "per-volume files and the cursor bake's debug_probe.txt go in the same folder",
            doc="The file Bake SH in Volumes writes; `//` is the folder of the saved `.blend`. An "
                "existing file there must be a `.shprobe` (see *What can go wrong*).",
            unit='FILE_PATH', option="--output"),
)

SETTINGS_BY_NAME = {s.name: s for s in SETTINGS}
PIXEL_FILTERS = SETTINGS_BY_NAME["pixel_filter"].choice_ids
RENDER_DEVICES = SETTINGS_BY_NAME["render_device"].choice_ids


def _cross_checks(s) -> Optional[str]:
    """Rules between settings (each single setting's limits are in :data:`SETTINGS`)."""
    if s.probe_representation != "SH" and not (s.placement == "ADAPTIVE" and s.file_version == "V3"):
        return ("Probe Representation (--probe-representation) 'Ambient cube' needs Placement Adaptive "
                "and File Version 3 (versions 1 and 2 hold SH only)")
    if s.max_cell_size < s.min_cell_size:
        return (f"Max Cell Size (m) (--max-cell-size) must be >= Min Cell Size (m) "
                f"(--min-cell-size) (got {s.max_cell_size:g} < {s.min_cell_size:g})")
    return None


def _validate(self):
    """Raise :class:`BakeError` naming the first invalid setting."""
    for spec in SETTINGS:
        why = spec.check(getattr(self, spec.name))
        if why:
            raise BakeError("Invalid setting: " + why)
    why = _cross_checks(self)
    if why:
        raise BakeError("Invalid setting: " + why)


def _from_props(cls, props, **overrides):
    """Settings from a ``Scene.schnee_probes`` PropertyGroup, with keyword overrides."""
    values = {f.name: getattr(props, f.name) for f in dataclasses.fields(cls) if hasattr(props, f.name)}
    values.update(overrides)
    return cls(**values)


#: Every setting of a bake; fields (names, types, defaults) come from :data:`SETTINGS`.
BakeSettings = dataclasses.make_dataclass(
    "BakeSettings",
    [(s.name, {"bool": bool, "int": int, "float": float}.get(s.kind, str), dataclasses.field(default=s.default))
     for s in SETTINGS],
    namespace={"validate": _validate, "from_props": classmethod(_from_props),
               "__doc__": "Every setting of a bake (fields and defaults: settings.SETTINGS)."},
)
BakeSettings.__module__ = __name__


# ------------------------------------------------------------------ bake.py
def parse_bool(text):
    t = str(text).lower()
    if t in ("1", "on", "true", "yes"):
        return True
    if t in ("0", "off", "false", "no"):
        return False
    import argparse
    raise argparse.ArgumentTypeError(f"expected on/off, got {text!r}")


def add_arguments(parser):
    """One ``bake.py`` option per setting. Values are checked by :meth:`BakeSettings.validate`
    (exit 3, naming the limit); enums and small integer ranges are argparse choices (exit 2)."""
    for s in SETTINGS:
        kw = {"dest": s.name, "default": None}
        default = s.format_value(s.default).strip("`")
        unit = f" {s.suffix}" if s.suffix else ""
        limits = "" if s.kind in ("bool", "enum") else "; " + s.limits_text().replace("`", "")
        help_text = f"{s.help} (default {default}{unit}{limits})"
        if s.kind == "bool":
            kw.update(type=parse_bool, metavar="{on,off}")
        elif s.kind == "enum":
            kw.update(choices=s.choice_ids)
        elif s.kind == "int":
            kw["type"] = int
            if s.minimum is not None and s.maximum is not None and s.maximum - s.minimum <= 8:
                kw["choices"] = range(int(s.minimum), int(s.maximum) + 1)
        elif s.kind == "float":
            kw["type"] = float
        if s.kind == "path":
            kw["metavar"] = "PATH"
        parser.add_argument(s.cli, help=help_text.replace("%", "%%"), **kw)


# ------------------------------------------------------------------ user guide
TABLE_BEGIN = "<!-- settings_table:begin -->"
TABLE_END = "<!-- settings_table:end -->"


_NUM = re.compile(r"\{num:(\w+)\}")


def guide_table(numbers: Optional[Mapping[str, Callable[[], str]]] = None) -> str:
    """The settings table of docs/user-guide.md (between TABLE_BEGIN and TABLE_END). A ``doc``'s
    measured figures are ``{num:KEY}`` placeholders filled from ``numbers`` (scripts/gen_numbers.py's
    NUMBERS, computed from bench/results/*.json); without it they stay as placeholders."""
    rows = ["<!-- generated from addon/schnee_probes/settings.py by scripts/gen_settings_table.py; "
            "do not edit -->",
            "| Setting (`bake.py` option) | Default | Limits | What it trades |",
            "|---|---|---|---|"]
    for s in SETTINGS:
        default = s.format_value(s.default) + (f" {s.suffix}" if s.suffix else "")
        text = s.doc or s.help
        if numbers is not None:
            text = _NUM.sub(lambda m: numbers[m[1]](), text)
        rows.append(f"| {s.label} (`{s.cli}`) | {default} | {s.limits_text()} | {text} |")
    return "\n".join(rows)
