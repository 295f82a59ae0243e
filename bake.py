"""Headless probe bake: ``blender -b scene.blend -P bake.py -- [options]``.

Runs Bake SH in Volumes (or, with ``--cursor X Y Z``, Bake SH at Cursor) on the opened .blend with
the scene's saved settings, each overridable by an option; ``--help`` lists them. Prints a progress
line, exits 0 on success and non-zero with a one-line reason on failure:

    1  unexpected error (a traceback follows)
    2  bad command line
    3  the bake refused its input or failed (missing collection, open volume, unsaved .blend, ...)
    4  the add-on or its native module could not be loaded
    130 interrupted (Ctrl+C)

The add-on package is taken from ``addon/`` next to this file when present, else from the installed
add-ons (legacy ``schnee_probes`` or the 4.2+ extension ``bl_ext.<repo>.schnee_probes``). The add-on
package carries a copy of this file: ``<installed add-on folder>/schnee_probes/bake.py``
(docs/install.md says where that is per Blender version). Nothing is written on failure; the .blend
itself is never saved.
"""
import argparse
import os
import sys
import time
import traceback

EXIT_UNEXPECTED, EXIT_USAGE, EXIT_BAKE, EXIT_ADDON, EXIT_INTERRUPT = 1, 2, 3, 4, 130


def _fail(code, message):
    # One line on stderr with the reason; os._exit would skip Blender's cleanup, sys.exit does not.
    sys.stderr.write(f"bake.py: error: {message}\n")
    sys.stderr.flush()
    sys.exit(code)


def _script_args():
    argv = sys.argv
    return argv[argv.index("--") + 1:] if "--" in argv else []


def _import_addon():
    """The add-on package: addon/ next to this file (source checkout), else the installed add-on
    (legacy ``schnee_probes`` or extension ``bl_ext.<repo>.schnee_probes``; this file also ships
    inside the package, next to its __init__.py)."""
    import importlib
    here = os.path.dirname(os.path.abspath(__file__))
    local = os.path.join(here, "addon")
    if os.path.isdir(os.path.join(local, "schnee_probes")) and local not in sys.path:
        sys.path.insert(0, local)
    name = _installed_package_name(here)
    try:
        addon = importlib.import_module(name)
        bake_core = importlib.import_module(name + ".bake_core")
        native = importlib.import_module(name + ".native")
    except ImportError as exc:
        _fail(EXIT_ADDON, f"cannot import the schnee_probes add-on ({exc}); install the add-on package "
                          "(Preferences > Add-ons/Get Extensions > Install from Disk) or, in a source "
                          "checkout, build it with 'cmake --build build'")
    problem = native.native_problem()
    if problem:
        _fail(EXIT_ADDON, problem)
    return addon, bake_core, native


def _installed_package_name(here):
    """``schnee_probes`` when importable as such (source checkout, legacy add-on), else the module
    name Blender gave the installed copy (a 4.2+ extension: ``bl_ext.user_default.schnee_probes``)."""
    import importlib.util
    if importlib.util.find_spec("schnee_probes") is not None:
        return "schnee_probes"
    try:
        import addon_utils
        mods = [m for m in addon_utils.modules() if m.__name__.split(".")[-1] == "schnee_probes"]
    except Exception:  # noqa: BLE001  (no add-on listing: the plain name gives the clear error)
        return "schnee_probes"
    for m in mods:  # prefer the copy this file ships in
        if os.path.dirname(os.path.abspath(m.__file__)) == here:
            return m.__name__
    return mods[0].__name__ if mods else "schnee_probes"


def _parser(bake_core):
    d = bake_core.BakeSettings()
    p = argparse.ArgumentParser(
        prog="blender -b scene.blend -P bake.py --",
        description="Bake Schnee SH light probes headless. Settings default to the values saved in "
                    "the .blend (Scene > Schnee Engine panel); the defaults shown are the add-on's.")
    a = p.add_argument
    a("--volume-collection", help=f"probe volume collection (default {d.volume_collection})")
    a("--min-cell-size", type=float, help=f"smallest octree cell in metres (default {d.min_cell_size})")
    a("--max-cell-size", type=float, help=f"largest octree cell in metres (default {d.max_cell_size})")
    a("--panorama-resolution", type=int, help=f"panorama width; height = width/2 (default {d.panorama_resolution})")
    a("--max-band", type=int, choices=range(5), help=f"highest SH band L (default {d.max_band})")
    a("--samples", type=int, help=f"Cycles samples per pixel (default {d.samples})")
    a("--max-bounces", type=int, help=f"light bounces (default {d.max_bounces})")
    a("--clamp-direct", type=float, help=f"direct sample clamp, 0 = off (default {d.clamp_direct})")
    a("--clamp-indirect", type=float, help=f"indirect sample clamp, 0 = off (default {d.clamp_indirect})")
    a("--pixel-filter", choices=bake_core.PIXEL_FILTERS, help=f"pixel filter (default {d.pixel_filter})")
    a("--filter-width", type=float, help=f"pixel filter width in px (default {d.filter_width})")
    a("--lights-visible", type=_bool, metavar="{on,off}", help="lamps seen by the probe cameras (default on)")
    a("--per-volume-files", type=_bool, metavar="{on,off}",
      help="one <volume>.shprobe per volume instead of probes.shprobe (default off)")
    a("--persistent-data", type=_bool, metavar="{on,off}", help="keep scene data between renders (default on)")
    a("--seed", type=int, help=f"Cycles seed (default {d.seed})")
    a("--default-sh-scale", type=float, help=f"SH scale in the file header (default {d.default_sh_scale})")
    a("--default-ambient", type=float, help=f"ambient term in the file header (default {d.default_ambient})")
    a("--output", dest="output_path", metavar="PATH",
      help=f"output .shprobe ('//' = folder of the .blend; default {d.output_path}); needed for an unsaved .blend")
    a("--cursor", type=float, nargs=3, metavar=("X", "Y", "Z"),
      help="bake one debug probe at this Blender-space position instead (Bake SH at Cursor)")
    a("--scene", help="scene name (default: the active scene)")
    a("--quiet", action="store_true", help="no progress line")
    return p


def _bool(text):
    t = text.lower()
    if t in ("1", "on", "true", "yes"):
        return True
    if t in ("0", "off", "false", "no"):
        return False
    raise argparse.ArgumentTypeError(f"expected on/off, got {text!r}")


def main():
    """Run the bake; every failure leaves through :func:`_fail` with its documented exit code.

    Blender ignores an uncaught exception of a ``-P`` script (exit status 0 unless it was started
    with ``--python-exit-code``), so anything unexpected is caught here and becomes exit 1.
    """
    try:
        _main()
    except SystemExit:
        raise
    except KeyboardInterrupt:
        _fail(EXIT_INTERRUPT, "interrupted; existing files are unchanged")
    except Exception as exc:  # noqa: BLE001  (the traceback is printed; the status must not be 0)
        traceback.print_exc()
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        _fail(EXIT_UNEXPECTED, f"unexpected {type(exc).__name__}" + (f": {reason}" if reason else ""))


def _main():
    import bpy

    addon, bake_core, native = _import_addon()
    parser = _parser(bake_core)
    # argparse exits 2 by itself on bad usage (with a usage line) and 0 after --help.
    args = parser.parse_args(_script_args())

    if not hasattr(bpy.types.Scene, "schnee_probes"):
        addon.register()
    scene = bpy.data.scenes.get(args.scene) if args.scene else bpy.context.scene
    if scene is None:
        _fail(EXIT_USAGE, f"no scene named '{args.scene}'")
    view_layer = scene.view_layers[0] if args.scene else bpy.context.view_layer

    overrides = {k: v for k, v in vars(args).items()
                 if v is not None and k not in ("cursor", "scene", "quiet")}
    settings = bake_core.BakeSettings.from_props(scene.schnee_probes, **overrides)
    mode = "CURSOR" if args.cursor else "VOLUMES"
    bake = bake_core.ProbeBake(scene, view_layer, settings, mode=mode, cursor=args.cursor,
                               log=(lambda line: None) if args.quiet else print)
    last = [0.0]

    def progress(b):
        now = time.perf_counter()
        if not args.quiet and (now - last[0] > 0.5 or b.done == b.total):
            last[0] = now
            end = "\n" if b.done == b.total else ""
            print("\r" + b.progress_line(), end=end, flush=True)

    try:
        result = bake.run(progress)
    except bake_core.BakeError as exc:
        _fail(EXIT_BAKE, str(exc))
    except native.SchneeError as exc:
        _fail(EXIT_BAKE, f"native core: {exc}")
    except OSError as exc:  # bake_core turns its own file errors into BakeError; this is a backstop
        _fail(EXIT_BAKE, f"cannot write {getattr(exc, 'filename', None) or 'the output'}: {exc}")
    except KeyboardInterrupt:
        _fail(EXIT_INTERRUPT, "interrupted; existing files are unchanged")
    for msg in result.messages:
        print("bake.py: " + msg)
    t = result.timings
    print(f"bake.py: {result.probe_count} probes in {result.seconds:.1f} s (placement {t['placement']:.2f} s, "
          f"render {t['render']:.2f} s, EXR write {t['write_exr']:.2f} s, projection {t['project']:.2f} s)")
    for f in result.files:
        print(f"bake.py: wrote {f}")


if __name__ == "__main__":
    main()
