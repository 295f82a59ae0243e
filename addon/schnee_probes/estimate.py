"""How many probes and how long, before a bake starts (plain Python: no ``bpy``).

The panel and the dialog show :func:`grid_cell_bound` of the volumes' bounding boxes with
:func:`estimate_seconds` of it; ``bake_core.ProbeBake.prepare`` logs the exact count after
placement with its estimate, and refuses above ``probe_limit`` unless confirmed; the progress line
refines the estimate with the measured times (``ProbeBake.remaining_seconds``). An Adaptive bake, whose
points are known only pass by pass, estimates its time in all from :func:`adaptive_points` at the
wall time per point it measures (``bake_plans.AdaptivePlan.forecast``). Both name the device
that renders (:func:`device_note`); the model is the CPU's whatever the device (Render Device GPU:
an upper estimate until the first probes are measured).
"""
import numpy as np

# Per-probe cost model of the time estimate: seconds per probe ≈ SECONDS_PER_PIXEL_SAMPLE × width ×
# height × samples. Calibrated on the sweep's 12.3-min run (bench/results/estimate_calibration.json,
# the project's 2-core machine; later runs on a busier machine replaced those scenes in
# sweep.json): in the bright closed room at 16-32 bounces every row, 32×16 to 128×64 px and 8 to
# 128 spp, took 3.46-3.84 µs per pixel-sample (defaults: 128×64 × 32 spp = 262144
# pixel-samples in 0.92-0.98 s); the courtyard took 0.6 µs, sky-only scenes 0.15 µs. The constant
# is just above the slowest room row, so before any probe is rendered the estimate is an upper one
# (a closed room); after the first probes it is replaced by the measured mean per probe (without
# the first, which also pays the scene upload). tests/python/test_estimate.py checks the model
# against every row of that run.
SECONDS_PER_PIXEL_SAMPLE = 3.9e-6
FIRST_PROBE_SECONDS = 1.6           # scene upload before the first render (0.7-1.6 s measured)
# Fixed cost of one render with persistent data (sync, film, EXR write, projection): in the bundled
# room at 128x64 px and 32 bounces one render took 0.069 s at 1 spp and 0.0375 s more per sample
# (1-32 spp), an intercept of 0.031 s. It matters at low samples, and twice per point for the
# Adaptive placement (two first rounds per point for the noise estimate).
RENDER_SECONDS = 0.03


def estimate_seconds(probes, settings, sky=False, renders=None) -> float:
    """Upper estimate of the bake time of ``probes`` probes (cost model: SECONDS_PER_PIXEL_SAMPLE);
    ``renders`` per probe defaults to the settings' placement (2 for Adaptive)."""
    w = settings.panorama_resolution
    if renders is None:
        renders = 2 if settings.placement == "ADAPTIVE" else 1
    per = SECONDS_PER_PIXEL_SAMPLE * w * (w // 2) * settings.samples + RENDER_SECONDS * renders
    total = probes * per + (FIRST_PROBE_SECONDS if probes else 0.0)
    if sky and settings.capture_sky:
        # One world-only render: no geometry, priced at the sky-only rate (0.15 µs).
        total += 0.15e-6 * settings.sky_resolution * (settings.sky_resolution // 2) * settings.samples
    return total


# The Adaptive bake's points (probes and test points, each rendered in rounds) per cell of
# grid_cell_bound, at Error Tolerance 0.03 and the render defaults: the bench scenes' bakes of issue
# 29 (bench/results/placement.md "The time estimate"): the room 0.75, the courtyard 0.46, the hall
# (sun mixed) 0.57; their geometric mean. Fewer at a larger tolerance: points ~ tolerance^-0.65
# (the room: 2400 points at 0.03, 1699 at 0.05; 1982 / 1485 / 837 at 0.05 / 0.1 / 0.2 in an
# earlier run).
ADAPTIVE_POINTS_PER_CELL = 0.58
ADAPTIVE_TOLERANCE_EXPONENT = 0.65


def adaptive_points(cells, tolerance) -> float:
    """The points an Adaptive bake is expected to render in ``cells`` cells of Min Cell Size
    (:func:`grid_cell_bound`) at ``tolerance`` (see ADAPTIVE_POINTS_PER_CELL)."""
    return ADAPTIVE_POINTS_PER_CELL * cells * (max(tolerance, 1e-6) / 0.03) ** -ADAPTIVE_TOLERANCE_EXPONENT


# The points of an Adaptive bake's later passes cost more than its first passes' mean: in the room
# 0.654 s per point over the bake against 0.52 s over its first 75 points (1.26x), in the courtyard
# 0.097 against 0.072 s (1.35x) (placement_{room,courtyard}_estimate.json, each beside one other
# bake). The forecast prices the points still to come at the mean so far times up to this factor,
# fading to 1 as the rendered points approach the expected count.
LATER_POINT_COST = 1.3


def forecast_seconds(elapsed, rendered, expected, per_point) -> float:
    """An Adaptive bake's time in all: ``elapsed`` so far plus the ``expected`` points not rendered
    yet (of ``rendered``) at the measured mean wall time ``per_point`` times the later points' factor
    (LATER_POINT_COST, fading with the share rendered)."""
    left = max(0.0, expected - rendered)
    share = min(1.0, rendered / expected) if expected > 0 else 1.0
    return elapsed + left * per_point * (1.0 + (LATER_POINT_COST - 1.0) * (1.0 - share))


def device_note(label: str) -> str:
    """What the estimate and progress lines append for the device that renders
    (``render_settings.device_label``): "on CPU (2 threads)". The cost model above was measured on
    this project's 2-core CPU, so on a GPU it says so: the estimate before the first probe is an
    upper one there, and the measured mean per probe replaces it after the first probes."""
    if label.startswith("GPU:") and not label.startswith("GPU: none"):
        return f"on {label}; the estimate before the first probes is a 2-core CPU's"
    return f"on {label}"


def format_duration(seconds) -> str:
    seconds = float(seconds)
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    if seconds < 2 * 86400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} days"


def grid_cell_bound(volumes, min_cell_size, per_volume) -> int:
    """An upper bound of the probe count: the cells of Min Cell Size covering the volumes'
    bounding box (per volume with One File per Volume), as the native grid counts them
    (docs/placement.md); probes are octree leaves of at least that size."""
    def cells(vols):
        pts = np.concatenate([np.asarray(v[1], dtype=np.float64).reshape(-1, 3) for v in vols])
        if len(pts) == 0:
            return 0
        ext = pts.max(axis=0) - pts.min(axis=0)
        dims = np.maximum(1, np.ceil(ext / min_cell_size - 1e-6))
        return int(np.prod(dims))
    if per_volume:
        return sum(cells([v]) for v in volumes)
    return cells(volumes)
