"""The equirect convention of DESIGN.md §3 against real Cycles renders (headless Blender 3.4).

One Blender launch (scripts/cycles_convention.py) renders tiny panoramas of a black world with one
small emissive square facing the camera, in known Blender-space directions. Then, here:
  (a) the brightest pixel, mapped through the DESIGN convention, points at the emitter (≤ 1 pixel
      diagonal), and the radiance-weighted centroid of the image to a fraction of a pixel;
  (b) the L1 coefficients of the projection, read as an engine-space vector (Y1∝y, Y2∝z, Y3∝x),
      point along the emitter's engine direction (x, z, −y), computed by numpy code written here and,
      when the native module is built, by schnee_probes.native.project_file / project_equirect;
  (c) the recorded energy L_00 equals the closed form S·Y_00·Ω of the square (box filter);
and, as a measurement for docs/sh.md, how Cycles' default Blackman–Harris 1.5 px pixel filter
changes L_00 for an emitter smaller than a pixel, depending on where it falls inside the pixel,
against a model built from Cycles' filter function.
Runtime: ~12 s here (one Blender start, 9 renders of at most 128×64, 256–1024 spp).
"""
import importlib
import json
import math
from pathlib import Path

import numpy as np
import pytest

from conftest import run_blender

SCRIPT = Path(__file__).resolve().parent / "scripts" / "cycles_convention.py"
Y00 = 0.5 / math.sqrt(math.pi)
Y1 = math.sqrt(3.0 / (4.0 * math.pi))
DISTANCE = 10.0
STRENGTH = 50.0


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def blender_to_engine(d):
    return np.array([d[0], d[2], -d[1]])


def pixel_dir(i, r, w, h):
    """DESIGN.md §3: column i, row r (row 0 at the top; fractional allowed) -> Blender direction."""
    phi = math.pi - 2.0 * math.pi * (i + 0.5) / w
    theta = math.pi * (r + 0.5) / h
    return np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)])


def angle_deg(a, b):
    return math.degrees(math.acos(max(-1.0, min(1.0, float(np.dot(unit(a), unit(b)))))))


def square_solid_angle(half, dist):
    """Solid angle of a square of half-side `half` centred at distance `dist`, facing the viewer:
    4·asin(u·v / sqrt((u²+d²)(v²+d²))) (closed form for a rectangle centred on the view axis)."""
    return 4.0 * math.asin(half * half / (half * half + dist * dist))


def half_size_for(pixels, w):
    """Half side of a square spanning `pixels` pixel widths (2π/W each) at DISTANCE."""
    return DISTANCE * math.tan(0.5 * pixels * 2.0 * math.pi / w)


def project_numpy(px, max_band=1):
    """Independent L<=1 projection: exact pixel solid angles, DESIGN mapping, engine-space basis."""
    h, w = px.shape[:2]
    r = np.arange(h)
    i = np.arange(w)
    theta = np.pi * (r + 0.5) / h
    phi = np.pi - 2.0 * np.pi * (i + 0.5) / w
    omega = (2.0 * np.pi / w) * (np.cos(np.pi * r / h) - np.cos(np.pi * (r + 1) / h))
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    bx, by, bz = st * np.cos(phi)[None, :], st * np.sin(phi)[None, :], np.broadcast_to(ct, (h, w))
    ex, ey, ez = bx, bz, -by  # Blender (x, y, z) -> engine (x, z, -y)
    basis = [np.full((h, w), Y00), Y1 * ey, Y1 * ez, Y1 * ex]
    rgb = px[..., :3].astype(np.float64) * omega[:, None, None]
    return np.array([[np.sum(rgb[..., c] * b) for c in range(3)] for b in basis[: (max_band + 1) ** 2]])


# Convention cases: Blender directions covering both hemispheres, the φ = ±π seam and a pole cap.
CONVENTION = {
    "upper_front": unit([1.0, 2.0, 0.7]),
    "lower_back": unit([-0.5, -1.0, -0.6]),
    "seam": unit([-1.0, 0.03, 0.2]),
    "near_pole": unit([0.2, 0.1, 1.0]),
    "minus_y": unit([0.0, -1.0, 0.0]),
}
CONV_W, CONV_H = 128, 64

# Filter measurement: 64×32, a sub-pixel emitter (0.5 px wide) centred on a pixel centre or on a
# pixel corner, rendered with the default Blackman–Harris 1.5 px and with a 1 px box.
FILT_W, FILT_H = 64, 32
FILTER_SPOTS = {"centre": (20.0, 10.0), "corner": (20.5, 10.5)}


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    out = tmp_path_factory.mktemp("cycles_convention")
    cases = []
    for name, d in CONVENTION.items():
        cases.append(dict(name=name, dir=d.tolist(), width=CONV_W, height=CONV_H, samples=256,
                          filter="BOX", filter_width=1.0, half_size=half_size_for(1.5, CONV_W),
                          distance=DISTANCE, strength=STRENGTH))
    for spot, (fi, fr) in FILTER_SPOTS.items():
        d = pixel_dir(fi, fr, FILT_W, FILT_H)
        for filt, width in (("BLACKMAN_HARRIS", 1.5), ("BOX", 1.0)):
            cases.append(dict(name=f"filter_{spot}_{filt.lower()}", dir=d.tolist(), width=FILT_W,
                              height=FILT_H, samples=1024, filter=filt, filter_width=width,
                              half_size=half_size_for(0.5, FILT_W), distance=DISTANCE, strength=STRENGTH))
    (out / "cases.json").write_text(json.dumps(cases))
    run_blender(SCRIPT, out, out / "cases.json", timeout=600)
    done = json.loads((out / "cases_done.json").read_text())
    assert [c["name"] for c in done] == [c["name"] for c in cases]
    return {c["name"]: dict(c, pixels=np.load(out / (c["name"] + ".npy"))) for c in done}


@pytest.mark.parametrize("name", list(CONVENTION))
def test_brightest_pixel_points_at_emitter(renders, name):
    case = renders[name]
    px = case["pixels"]
    h, w = px.shape[:2]
    assert (w, h) == (CONV_W, CONV_H)
    lum = px[..., :3].sum(axis=2)
    assert np.isfinite(px).all() and lum.max() > 0.5 * STRENGTH, "the emitter is not in the image"
    r, i = np.unravel_index(np.argmax(lum), lum.shape)
    d = np.array(case["dir"])
    pixel_deg = 360.0 / w
    # The emitter (1.5 px wide) covers the brightest pixel, so its centre is within a pixel diagonal.
    assert angle_deg(pixel_dir(i, r, w, h), d) <= math.sqrt(2) * pixel_deg, (name, i, r)
    # Radiance-weighted centroid of all pixel directions: within 0.25 px (box filter, symmetric).
    omega = (2 * np.pi / w) * (np.cos(np.pi * np.arange(h) / h) - np.cos(np.pi * (np.arange(h) + 1) / h))
    acc = np.zeros(3)
    for rr, ii in zip(*np.nonzero(lum > 0)):
        acc += lum[rr, ii] * omega[rr] * pixel_dir(ii, rr, w, h)
    assert angle_deg(acc, d) <= 0.25 * pixel_deg, (name, angle_deg(acc, d))


@pytest.mark.parametrize("name", list(CONVENTION))
def test_l1_points_along_engine_direction(renders, name):
    case = renders[name]
    coeffs = project_numpy(case["pixels"])
    lum = coeffs.sum(axis=1)
    l1 = np.array([lum[3], lum[1], lum[2]])  # engine (x, y, z) from Y3∝x, Y1∝y, Y2∝z
    e = blender_to_engine(np.array(case["dir"]))
    # A small source's L1 vector is Y1·(flux-weighted mean direction): along the emitter's axis.
    assert angle_deg(l1, e) <= 1.0, (name, angle_deg(l1, e))
    # Magnitude: |L1| = Y1·S·∫cos ≈ Y1/Y00·L00 for a source this small (cos 1° ≈ 1 − 1.5e-4).
    assert np.linalg.norm(l1) == pytest.approx(Y1 / Y00 * lum[0], rel=1e-3)


@pytest.mark.parametrize("name", list(CONVENTION))
def test_energy_matches_closed_form(renders, name):
    """L00 = S·Y00·Ω(square). Box filter: each direction is sampled by exactly one pixel, so the only
    errors are edge-coverage noise (256 spp; measured ≤ 0.3 %) and the in-pixel sin θ variation:
    1 % tolerance."""
    case = renders[name]
    coeffs = project_numpy(case["pixels"], max_band=0)
    want = case["strength"] * Y00 * square_solid_angle(case["half_size"], case["distance"])
    assert coeffs[0] == pytest.approx([want] * 3, rel=0.01)


def _native_or_skip():
    try:
        importlib.import_module("schnee_probes._schnee_native")
    except ImportError as exc:  # explicit, with the reason, never silent
        pytest.skip(f"native module not built ({exc}); run cmake --build build -j2")
    from schnee_probes import native
    return native


@pytest.mark.parametrize("name", list(CONVENTION))
def test_native_projection_matches(renders, name):
    """The C projection of the EXR (OpenImageIO) equals the numpy one of Blender's pixels (L ≤ 1),
    and project_equirect of the top-row-first array equals project_file: same orientation."""
    native = _native_or_skip()
    case = renders[name]
    from_file = native.project_file(case["exr"], max_band=1, negative="error")
    from_array = native.project_equirect(np.ascontiguousarray(case["pixels"]), max_band=1)
    ref = project_numpy(case["pixels"])
    scale = np.abs(ref[0]).max()
    np.testing.assert_allclose(from_file, ref, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(from_array, from_file, rtol=0, atol=1e-12 * scale)
    lum = from_file.sum(axis=1)
    e = blender_to_engine(np.array(case["dir"]))
    assert angle_deg([lum[3], lum[1], lum[2]], e) <= 1.0


def cycles_blackman_harris(x, width):
    """Cycles' filter_func_blackman_harris; filter_table() doubles the user width first, so the
    default "1.5 px" filter has support ±1.5 px (scene/film.cpp)."""
    w = 2.0 * width
    t = 2.0 * np.pi * (x / w + 0.5)
    v = 0.35875 - 0.48829 * np.cos(t) + 0.14128 * np.cos(2 * t) - 0.01168 * np.cos(3 * t)
    return np.where(np.abs(x) <= w / 2, v, 0.0)


def filter_gain_1d(centre, half, width=1.5):
    """Energy a source spanning [centre ± half] (pixel units, 0 = a pixel centre) leaves in the
    image: Σ_n k(n − x) / ∫k averaged over the source. Exactly 1 for a 1 px box at any x."""
    xs = np.linspace(-1.5 * width, 1.5 * width, 200001)
    integral = np.trapz(cycles_blackman_harris(xs, width), xs)
    x = np.linspace(centre - half, centre + half, 2001)
    return float(np.mean(sum(cycles_blackman_harris(n - x, width) for n in range(-6, 7)) / integral))


def test_pixel_filter_energy(renders, capsys):
    """Measurement behind docs/sh.md. A 0.5 px emitter's recorded energy L00 against the closed form.
    Box 1 px is a partition of unity (every direction belongs to exactly one pixel): ratio 1 wherever
    the emitter falls (tolerance 1.5 %: 1024 spp coverage noise, measured ≤ 1 %). Blackman–Harris
    "1.5 px" spans ±1.5 px and its copies at pixel spacing do not sum to 1, so the energy depends on
    where the emitter sits inside the pixel: the model Π_axes filter_gain_1d (emitter footprint 0.5 px
    in θ, 0.5/sin θ px in φ) predicts the BH/box ratio; measured agreement ≤ 0.3 %, tolerance 1 %."""
    ratios, model = {}, {}
    for spot, (fi, fr) in FILTER_SPOTS.items():
        for filt in ("blackman_harris", "box"):
            case = renders[f"filter_{spot}_{filt}"]
            l00 = project_numpy(case["pixels"], max_band=0)[0].mean()
            want = case["strength"] * Y00 * square_solid_angle(case["half_size"], case["distance"])
            ratios[(spot, filt)] = l00 / want
        sin_theta = math.sin(math.pi * (fr + 0.5) / FILT_H)
        frac = fi - math.floor(fi)
        model[spot] = filter_gain_1d(frac, 0.25 / sin_theta) * filter_gain_1d(frac, 0.25)
    with capsys.disabled():
        print("\nL00 / closed form, 0.5 px emitter at 64x32, 1024 spp:")
        for spot in FILTER_SPOTS:
            print(f"  {spot:7s} box {ratios[(spot, 'box')]:.4f}  blackman-harris 1.5 "
                  f"{ratios[(spot, 'blackman_harris')]:.4f}  BH/box {ratios[(spot, 'blackman_harris')] / ratios[(spot, 'box')]:.4f}"
                  f"  model {model[spot]:.4f}")
    for spot in FILTER_SPOTS:
        assert ratios[(spot, "box")] == pytest.approx(1.0, rel=0.015)
        bh_over_box = ratios[(spot, "blackman_harris")] / ratios[(spot, "box")]
        assert bh_over_box == pytest.approx(model[spot], rel=0.01)
    assert model["centre"] > 1.03 and model["corner"] < 0.97  # the effect is real, not noise
