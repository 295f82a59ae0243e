"""A region rebake inside one volume, closed form (addon/schnee_probes/region.py; docs/region-rebake.md),
without Blender: the Adaptive refinement (adaptive.AdaptiveGroup, the bake's own state machine) is
driven by closed-form fields instead of renders, as tests/python/test_adaptive.py does.

The previous bake holds the linear field L(p) = 1 + 0.2 x (+ a constant sun term), which trilinear
interpolation reproduces exactly, so it refines nothing. The edit changes the light inside the
region R (x in [3, 5]) by a bump; the rebake keeps the previous bake's points outside R (region.py's
filter over a kept-points file written and read back in the journal format) and evaluates the new
field only inside R. Then, along the volume's axis: the interpolated field is continuous at R's
border (no jump above 1e-6 between x - 1e-9 and x + 1e-9 anywhere), equals the previous bake's field
(1e-12) and L (to the 2e-3 of the nodes on the volume's faces, rendered 1 cm inside) in every leaf
with no corner in R, the leaves that split are only those that meet R, and the probes outside R
hold the previous bake's bits. Runtime < 2 s."""
import numpy as np

from conftest import requires_native
from schnee_probes import adaptive, journal, native, region
from test_adaptive import VOLUME, drive, sh_of

pytestmark = requires_native

LO, HI = np.array([3.0, -1.0, -1.0]), np.array([5.0, 3.0, 3.0])   # R, engine space


def linear(p):
    return np.array([sh_of(1.0 + 0.2 * x, 0.5) for x in p[:, 0]])


def edited(p):
    """The light after the edit: a bump of height 2 peaking at x = 4 inside R, L elsewhere."""
    return np.array([sh_of(1.0 + 0.2 * x + 2.0 * max(0.0, 1.0 - abs(x - 4.0)), 0.5) for x in p[:, 0]])


def _group():
    return adaptive.AdaptiveGroup("hall", "", [VOLUME], [], 0.5, 2.0, 0.05)


def _leaves(group):
    """{(x, y, z, level)} of the finished tree's leaves and their metre bounds (lo, hi) per leaf."""
    info = group.tree.info()
    size = 0.5 * 2.0 ** adaptive.leaf_levels(info).astype(float)
    lo = info["leaves"][:, :3] * info["min_cell"] + np.asarray(info["origin"])
    return {tuple(x) for x in info["leaves"].tolist()}, lo, lo + size


def test_region_rebake_is_continuous_and_keeps_the_outside(tmp_path):
    before = _group()
    cache = drive(before, linear)
    assert before.passes[0].split == 0            # a linear field refines nothing
    # The previous bake's kept points, written and read back as a bake writes them.
    keys = {journal.key_of(p): cache.coeffs[i] for i, p in enumerate(cache.positions)}
    manifest = journal.make_manifest({"settings": "s"})
    journal.write_whole(str(tmp_path / "probes.shprobe.points"), manifest, 9, keys, {})
    kept = region.kept_outside(journal.read(str(tmp_path / "probes.shprobe.points")).values, (LO, HI))
    assert 0 < len(kept) < len(keys)

    def rebake_field(p):   # the store's rule: a kept point stands for its render
        value = kept.get(journal.key_of(p[0]))
        return edited(p) if value is None else value[None]
    after = _group()
    cache2 = drive(after, rebake_field)
    assert any(rec.split for rec in after.passes)  # the bump refines

    coeffs, _ = after.probe_values(cache2)
    x = np.linspace(0.0, 8.0, 8001)
    line = np.stack([x, np.full_like(x, 1.0), np.full_like(x, 1.0)], axis=1)
    got = after.tree.interpolate(line, coeffs)[:, 0, 0]
    # Continuous: across every point of the line, in particular R's borders x = 3 and x = 5.
    eps = 1e-9
    left = after.tree.interpolate(line - [eps, 0, 0], coeffs)[:, 0, 0]
    right = after.tree.interpolate(line + [eps, 0, 0], coeffs)[:, 0, 0]
    ok = (x > eps) & (x < 8.0 - eps)
    assert np.max(np.abs(left[ok] - right[ok])) < 1e-6
    # The closed form in every leaf with no corner in R.
    _, lo, hi = _leaves(after)
    far = (hi[:, 0] < LO[0]) | (lo[:, 0] > HI[0])
    in_far = np.zeros(len(x), dtype=bool)
    for a, b in zip(lo[far, 0], hi[far, 0]):
        in_far |= (x >= a) & (x <= b)
    assert in_far.sum() > 2000
    # Nodes on the volume's faces render 1 cm inside (adaptive.py), so L is met to 0.2 * 0.01 there.
    assert np.max(np.abs(got[in_far] - (1.0 + 0.2 * x[in_far]))) < 0.2 * 0.01 + 1e-12
    prev = before.tree.interpolate(line, before.probe_values(cache)[0])[:, 0, 0]
    assert np.max(np.abs(got[in_far] - prev[in_far])) < 1e-12   # and there the previous bake's field
    # The refinement re-ran inside R only: the leaves that do not meet R are the previous ones.
    old, _, _ = _leaves(before)
    new, lo, hi = _leaves(after)
    meets = np.all((lo <= HI) & (hi >= LO), axis=1)
    info = after.tree.info()
    outside = {tuple(v) for v, m in zip(info["leaves"].tolist(), meets) if not m}
    assert outside <= old and len(new - old) > 0
    # The probes outside R: the previous bake's bits.
    outside_probes = 0
    for i, j in enumerate(after.probe_index):
        p = cache2.positions[j]
        if np.any(p < LO) or np.any(p > HI):
            outside_probes += 1
            assert coeffs[i].tobytes() == keys[journal.key_of(p)].tobytes()
    assert outside_probes > 0


def previous_field(p):
    """The previous bake's light: L plus a bump of height 1 at x = 1, outside R (the tree refines there)."""
    return np.array([sh_of(1.0 + 0.2 * x + max(0.0, 1.0 - 2.0 * abs(x - 1.0)), 0.5) for x in p[:, 0]])


def edited_field(p):
    """After the edit: the previous light plus the bump of :func:`edited` inside R."""
    return previous_field(p) + edited(p) - linear(p)


def _bake_file(path, group, coeffs, validity):
    native.write_shprobe_v3(str(path), group.tree, np.asarray(coeffs, np.float32), validity=validity)
    return native.read_shprobe(str(path))


def _records(f):
    """{probe lattice node: (coefficient bytes, validity bytes)} of a version 3 file."""
    info = native.interpolation_from_file(f.path).info()
    return {tuple(int(v) for v in n): (f.coeffs[i].tobytes(), f.validity[i].tobytes())
            for i, n in enumerate(info["probe_lattice"])}


def _rebake(tmp_path, kept_tree: bool):
    """The previous bake of previous_field, then a region rebake of R whose renders outside R are off
    by 1 % near R (what Cycles shows: a point whose relocation or solid test sees the edit from beyond
    the box, or whose later rounds a test meeting the box asked differently, renders anew)."""
    before = _group()
    cache = drive(before, previous_field)
    old_path = tmp_path / "hall.shprobe"
    old = _bake_file(old_path, before, *before.probe_values(cache))
    old.path = str(old_path)

    def rebake_field(p):
        x = p[0, 0]
        if LO[0] <= x <= HI[0]:
            return edited_field(p)
        near = 1.0 if x < LO[0] - 1.0 or x > HI[0] + 1.0 else 1.01   # the renders that see the edit
        return previous_field(p) * near
    after = _group()
    if kept_tree:
        after.kept = region.KeptTree(str(old_path), (LO, HI), after.origin, after.min_cell)
    cache2 = drive(after, rebake_field)
    coeffs, validity = after.probe_values(cache2)
    if kept_tree:
        rows, rec, valid = after.kept.records(after.kept.previous_rows(after.tree.probe_lattice()))
        coeffs = coeffs.astype(np.float32)
        coeffs[rows], validity = rec, validity.copy()
        validity[rows] = valid
    new_path = tmp_path / "hall-rebaked.shprobe"
    new = _bake_file(new_path, after, coeffs, validity)
    new.path = str(new_path)
    return before, after, old, new


def _boxes(group):
    info = group.tree.info()
    lo = info["leaves"][:, :3].astype(np.int64)
    return adaptive.leaf_keys(info), lo, lo + (1 << adaptive.leaf_levels(info).astype(np.int64))


def _kept_differences(before, after, old, new):
    """(previous leaves outside R that the rebake lost, outside-R records of shared nodes that differ)."""
    h, origin = after.min_cell, np.asarray(after.origin)
    def meets(lo, hi):
        return np.all((origin + lo * h <= HI) & (origin + hi * h >= LO), axis=1)
    old_keys, olo, ohi = _boxes(before)
    new_keys, nlo, nhi = _boxes(after)
    new_set, new_meets = set(new_keys), meets(nlo, nhi)
    lost = 0
    for k, lo, hi, m in zip(old_keys, olo, ohi, meets(olo, ohi)):
        inside_new_region_leaf = np.any(new_meets & np.all((nlo <= lo) & (nhi >= hi), axis=1))
        if not m and k not in new_set and not inside_new_region_leaf:
            lost += 1
    a, b = _records(old), _records(new)
    differ = 0
    for node, rec in b.items():
        p = origin + np.array(node) * h
        if (np.any(p < LO) or np.any(p > HI)) and node in a and a[node] != rec:
            differ += 1
    return lost, differ, sum(1 for n in b if n in a and np.any((origin + np.array(n) * h < LO)
                                                               | (origin + np.array(n) * h > HI)))


def test_without_the_kept_tree_renders_that_see_the_edit_change_the_outside(tmp_path):
    """The failure the kept tree mends (so the next test can fail): the 1 % renders near R move the
    outside's records."""
    before, after, old, new = _rebake(tmp_path, kept_tree=False)
    lost, differ, shared = _kept_differences(before, after, old, new)
    assert differ > 0 and shared > differ


def test_kept_tree_holds_the_previous_leaves_and_bits_outside_the_region(tmp_path):
    before, after, old, new = _rebake(tmp_path, kept_tree=True)
    assert any(rec.split for rec in before.passes) and any(rec.kept for rec in after.passes)
    lost, differ, shared = _kept_differences(before, after, old, new)
    assert lost == 0 and differ == 0 and shared > 20
    # Inside R the edit is baked: the bump's peak, interpolated, within the tolerance of the edited light.
    peak = np.array([[4.0, 1.0, 1.0]])
    got = after.tree.interpolate(peak, new.coeffs.astype(np.float64), new.validity)[0, 0, 0]
    assert abs(got - edited_field(peak)[0, 0, 0]) < 0.05 * edited_field(peak)[0, 0, 0]
    # Continuous across R's borders (x = 3 and x = 5) and everywhere on the line.
    x = np.linspace(1e-6, 8.0 - 1e-6, 4001)
    line = np.stack([x, np.full_like(x, 1.0), np.full_like(x, 1.0)], axis=1)
    c = new.coeffs.astype(np.float64)
    left = after.tree.interpolate(line - [1e-9, 0, 0], c, new.validity)[:, 0, 0]
    right = after.tree.interpolate(line + [1e-9, 0, 0], c, new.validity)[:, 0, 0]
    assert np.max(np.abs(left - right)) < 1e-6
