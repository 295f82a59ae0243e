"""Scene geometry for probe placement, as flat numpy arrays in engine space (DESIGN.md §2).

Only Blender-API work lives here: evaluated meshes (modifiers, instances) are read with
``foreach_get`` and transformed with numpy; placement itself is native (``native.place_probes``).
"""
import numpy as np

from .native import BLENDER_TO_ENGINE

# Object types that evaluate to a mesh (``Object.to_mesh()``).
MESH_LIKE = {'MESH', 'CURVE', 'SURFACE', 'FONT', 'META'}


def blender_to_engine(points):
    """(N, 3) Blender world positions or directions -> engine space: (x, y, z) -> (x, z, -y)."""
    return np.asarray(points, dtype=np.float64) @ BLENDER_TO_ENGINE.T


def engine_to_blender(points):
    """Inverse of :func:`blender_to_engine`: engine (x, y, z) -> Blender (x, -z, y)."""
    return np.asarray(points, dtype=np.float64) @ BLENDER_TO_ENGINE


def _local_triangles(ob_eval):
    """(vertices (V, 3) float64 object space, triangles (T, 3) uint32) of an evaluated object."""
    mesh = ob_eval.to_mesh()
    try:
        mesh.calc_loop_triangles()
        verts = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", verts)
        tris = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", tris)
    finally:
        ob_eval.to_mesh_clear()
    return verts.reshape(-1, 3).astype(np.float64), tris.reshape(-1, 3).astype(np.uint32)


def _world_engine(verts_local, matrix_world):
    m = np.array(matrix_world, dtype=np.float64)
    world = verts_local @ m[:3, :3].T + m[:3, 3]
    return np.ascontiguousarray(blender_to_engine(world))


def gather_geometry(depsgraph, exclude_names=frozenset()):
    """Every render-visible mesh-like object and instance of the evaluated scene, except those whose
    original (or instancing parent) is named in ``exclude_names``.

    Returns a list of ``(name, vertices (V, 3) float64, triangles (T, 3) uint32)`` in engine space.
    Each instance is its own entry (world-space copy); the evaluated mesh of an object is read once.
    """
    cache = {}
    out = []
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type not in MESH_LIKE:
            continue
        owner = inst.parent if inst.is_instance and inst.parent is not None else ob
        if owner.original.name in exclude_names or ob.original.name in exclude_names:
            continue
        if owner.original.hide_render:
            continue
        key = ob.name
        if key not in cache:
            cache[key] = _local_triangles(ob)
        verts, tris = cache[key]
        if len(tris) == 0:
            continue
        name = ob.name if not inst.is_instance else f"{owner.name}/{ob.name}"
        out.append((name, _world_engine(verts, inst.matrix_world), tris))
    return out


def volume_mesh(ob, depsgraph):
    """``(name, vertices, triangles)`` of one probe-volume object in engine space (modifiers applied)."""
    ob_eval = ob.evaluated_get(depsgraph)
    verts, tris = _local_triangles(ob_eval)
    return ob.name, _world_engine(verts, ob_eval.matrix_world), tris
