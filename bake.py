"""Headless probe bake: ``blender -b scene.blend -P bake.py -- [options]``.

Runs Bake SH in Volumes (or, with ``--cursor X Y Z``, Bake SH at Cursor) on the opened .blend with
the scene's saved settings, each overridable by an option; ``--help`` lists them. Prints a progress
line, exits 0 on success and non-zero with a one-line reason on failure:

    1   unexpected error (a traceback follows)
    2   bad command line
    3   the bake refused its input or failed (missing collection, open volume, unsaved .blend,
        an output that is not a .shprobe, another bake writing the same output, more probes than
        --probe-limit without --allow-large, ...)
    4   the add-on or its native module could not be loaded
    130 cancelled by SIGINT (Ctrl+C)
    143 cancelled by SIGTERM

SIGINT and SIGTERM cancel the bake as Esc does in Blender: the current probe's render finishes,
then the render settings are restored, the temporary files removed and nothing is written (the
previous output stays as it was). Before the first render a line gives the probe count and an
estimated time.

The add-on package is taken from ``addon/`` next to this file when present, else from the installed
add-ons (legacy ``schnee_probes`` or the 4.2+ extension ``bl_ext.<repo>.schnee_probes``). The add-on
package carries a copy of this file: ``<installed add-on folder>/schnee_probes/bake.py``
(docs/install.md says where that is per Blender version). Nothing is written on failure; the .blend
itself is never saved.
"""
import argparse
import os
import signal
import sys
import time
import traceback

EXIT_UNEXPECTED, EXIT_USAGE, EXIT_BAKE, EXIT_ADDON = 1, 2, 3, 4
EXIT_INTERRUPT = 128 + signal.SIGINT    # 130
EXIT_TERMINATED = 128 + signal.SIGTERM  # 143


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
        settings = importlib.import_module(name + ".settings")
    except ImportError as exc:
        _fail(EXIT_ADDON, f"cannot import the schnee_probes add-on ({exc}); install the add-on package "
                          "(Preferences > Add-ons/Get Extensions > Install from Disk) or, in a source "
                          "checkout, build it with 'cmake --build build'")
    problem = native.native_problem()
    if problem:
        _fail(EXIT_ADDON, problem)
    return addon, bake_core, native, settings


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


def _shard(text):
    try:
        k, n = (int(x) for x in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not K/N (e.g. 0/4)") from None
    if not 0 <= k < n:
        raise argparse.ArgumentTypeError(f"'{text}': K must be in 0..N-1")
    return k, n


def _positive(text):
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"'{text}' is not a positive integer")
    return n


def _parser(settings):
    # allow_abbrev=False: a mistyped or shortened option is an error, not another option taken by
    # its prefix (issue 31: "--sbatch PATH" became --sbatch-option and an "#SBATCH PATH" line).
    p = argparse.ArgumentParser(
        prog="blender -b scene.blend -P bake.py --", allow_abbrev=False,
        description="Bake Schnee SH light probes headless. Settings default to the values saved in "
                    "the .blend (Scene > Schnee Engine panel); the defaults shown are the add-on's.")
    settings.add_arguments(p)  # one option per setting (settings.py)
    a = p.add_argument
    a("--cursor", type=float, nargs=3, metavar=("X", "Y", "Z"),
      help="bake one debug probe at this Blender-space position instead (Bake SH at Cursor)")
    a("--only-volume", metavar="NAME",
      help="rebake the probe volume NAME alone after an edit: write only sh_coeffs/NAME.shprobe and keep every "
           "other volume's file, the sky and the sun as the previous bake left them (needs One File per Volume "
           "and a previous bake with the same settings; docs/region-rebake.md)")
    a("--region", type=float, nargs=6, metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
      help="with --only-volume: rebake only inside this box (Blender coordinates, two opposite corners); the "
           "previous bake's points outside it are kept (docs/region-rebake.md)")
    a("--allow-large", action="store_true",
      help="bake even when the probe count is above --probe-limit (otherwise refused, exit 3)")
    a("--shard", type=_shard, metavar="K/N",
      help="farm bakes: bake only share K of N (probes i with i %% N == K) into the shard journal "
           "<output>.shard-K-of-N.journal and write no .shprobe (docs/farm.md)")
    a("--merge-shards", type=_positive, metavar="N",
      help="farm bakes: take every probe from the N shard journals and write the output files")
    a("--farm", choices=["slurm"],
      help="submit the bake to a farm instead of baking here: N shard jobs (--shards) and the merge "
           "job that writes the files once every shard succeeded (docs/farm.md)")
    a("--shards", type=_positive, default=4, metavar="N", help="with --farm: number of shards (default 4)")
    a("--sbatch-option", action="append", default=[], metavar="OPT",
      help="with --farm slurm: an #SBATCH option for every job, e.g. --sbatch-option=--partition=bake "
           "(repeatable)")
    a("--sbatch", default="sbatch", metavar="PATH",
      help="with --farm slurm: the sbatch program that submits the jobs (default: sbatch found on PATH)")
    a("--restart", action="store_true",
      help="discard this bake's journal (the probes a cancelled or crashed run kept) and bake from scratch; with "
           "--farm: remove the shard journals and the merge's journal before submitting")
    a("--scene", help="scene name (default: the active scene)")
    a("--quiet", action="store_true", help="no progress line")
    return p


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

    addon, bake_core, native, settings = _import_addon()
    parser = _parser(settings)
    # argparse exits 2 by itself on bad usage (with a usage line) and 0 after --help.
    args = parser.parse_args(_script_args())
    _check_combinations(parser, args)

    if not hasattr(bpy.types.Scene, "schnee_probes"):
        addon.register()
    scene = bpy.data.scenes.get(args.scene) if args.scene else bpy.context.scene
    if scene is None:
        _fail(EXIT_USAGE, f"no scene named '{args.scene}'")
    view_layer = scene.view_layers[0] if args.scene else bpy.context.view_layer

    overrides = {k: v for k, v in vars(args).items()
                 if v is not None and k not in ("cursor", "scene", "quiet", "allow_large", "shard", "merge_shards",
                                                "restart", "farm", "shards", "sbatch_option", "sbatch",
                                                "only_volume", "region")}
    bake_settings = settings.BakeSettings.from_props(scene.schnee_probes, **overrides)
    if args.farm:
        _submit(args, bake_core, bake_settings, scene, view_layer)
        return
    mode = "CURSOR" if args.cursor else "VOLUMES"
    bake = bake_core.ProbeBake(scene, view_layer, bake_settings, mode=mode, cursor=args.cursor,
                               log=(lambda line: None) if args.quiet else print,
                               allow_large=args.allow_large, shard=args.shard, merge_shards=args.merge_shards,
                               restart=args.restart, only_volume=args.only_volume,
                               region=args.region)
    last = [0.0]

    def progress(b):
        now = time.perf_counter()
        if not args.quiet and (now - last[0] > 0.5 or b.done == b.total):
            last[0] = now
            end = "\n" if b.done == b.total else ""
            print("\r" + b.progress_line(), end=end, flush=True)

    def note(line):
        sys.stderr.write(line.lstrip("\n") + "\n")
        sys.stderr.flush()

    # SIGINT / SIGTERM cancel like Esc; the bake restores the scene and removes its files.
    with bake_core.CancelOnSignals(bake, (signal.SIGINT, signal.SIGTERM), force=True, log=note) as sig:
        try:
            result = bake.run(progress)
        except bake_core.BakeCancelled as exc:
            kept = bake_core.kept_message(bake)
            kept = f"; {kept}" if kept else ""
            if sig.caught:
                first = sig.caught[0]
                _fail(128 + first, f"cancelled by {signal.Signals(first).name}; render settings "
                                   f"restored, existing files unchanged{kept}")
            _fail(EXIT_BAKE, str(exc) + kept)
        except bake_core.BakeError as exc:
            kept = bake_core.kept_message(bake)
            _fail(EXIT_BAKE, str(exc) + (f"; {kept}" if kept else ""))
        except native.SchneeError as exc:
            _fail(EXIT_BAKE, f"native core: {exc}")
        except OSError as exc:  # bake_core turns its own file errors into BakeError; a backstop
            _fail(EXIT_BAKE, f"cannot write {getattr(exc, 'filename', None) or 'the output'}: {exc}")
        except KeyboardInterrupt:
            _fail(EXIT_INTERRUPT, "interrupted; existing files are unchanged")
    _report(result)


def _check_combinations(parser, args):
    """Options that exclude each other: argparse's usage error (exit 2) naming both."""
    if args.shard is not None and args.merge_shards is not None:
        parser.error("--shard and --merge-shards cannot be combined: a farm job either bakes one shard "
                     "(--shard K/N) or, once every shard is baked, merges the N shard journals into the "
                     "output (--merge-shards N); run them as separate jobs")
    if args.cursor is not None and (args.shard is not None or args.merge_shards is not None):
        parser.error(f"--cursor cannot be combined with {'--shard' if args.shard else '--merge-shards'}: "
                     "farm shards bake volumes; Bake SH at Cursor is one probe, baked here")
    if args.region is not None and args.only_volume is None:
        parser.error("--region needs --only-volume NAME: the volume whose probes inside the box are baked again")
    if args.cursor is not None and args.only_volume is not None:
        parser.error("--cursor cannot be combined with --only-volume: Bake SH at Cursor bakes one probe, "
                     "--only-volume rebakes one probe volume")


def _submit(args, bake_core, bake_settings, scene, view_layer):
    """--farm slurm: write the batch scripts next to the output and submit them; bake nothing here.
    Journals the jobs would refuse (another bake's) are reported first; --restart removes them."""
    import importlib

    import bpy

    package = bake_core.__name__.rsplit(".", 1)[0]
    farm = importlib.import_module(package + ".farm")
    if args.cursor or args.shard or args.merge_shards:
        _fail(EXIT_USAGE, "--farm bakes volumes; it cannot be combined with --cursor, --shard or --merge-shards")
    if not bpy.data.filepath:
        _fail(EXIT_USAGE, "--farm needs a saved .blend (farm nodes open the file)")
    adaptive = importlib.import_module(package + ".adaptive")
    stages = 1
    if bake_settings.placement == "ADAPTIVE":  # one job array per refinement stage
        stages = adaptive.stage_bound(bake_settings.min_cell_size, bake_settings.max_cell_size)
    try:
        output = bake_core.abspath(bake_settings.output_path)
        if args.only_volume:  # what every job would refuse, refused once here (nothing submitted)
            region, plans = (importlib.import_module(f"{package}.{m}") for m in ("region", "bake_plans"))
            plans.check_rebake(region.VolumeRebake(args.only_volume, args.region), bake_settings, output)
        farm.find_sbatch(args.sbatch)   # before --restart removes anything

        def manifest():
            fingerprint, journal = (importlib.import_module(f"{package}.{m}") for m in ("fingerprint", "journal"))
            return journal.make_manifest(fingerprint.parts(scene, view_layer, bake_settings), scene=scene.name,
                                         blend=bpy.data.filepath)
        removed = farm.prepare_journals(farm.job_journals(output, args.shards, args.only_volume), manifest,
                                        restart=args.restart)
        for path in removed:
            print(f"bake.py: --restart: removed {path}")
        ids = farm.submit_slurm(bpy.app.binary_path, os.path.abspath(bpy.data.filepath), os.path.abspath(__file__),
                                farm.forwarded_args(_script_args(), output=output), args.shards, output,
                                sbatch_options=args.sbatch_option, sbatch=args.sbatch, stages=stages)
    except (farm.FarmError, bake_core.BakeError, OSError) as exc:
        _fail(EXIT_BAKE, f"farm submission failed: {exc}")
    print(f"bake.py: submitted {stages} shard array(s) {', '.join(ids[:-1])} ({args.shards} tasks each, one per "
          f"placement stage, each after the previous succeeded) and merge job {ids[-1]}; scripts and logs in "
          f"{farm.farm_folder(output)}")


def _report(result):
    for msg in result.messages:
        print("bake.py: " + msg)
    t = result.timings
    if result.passes:
        print(f"bake.py: adaptive placement: {len(result.passes)} pass(es), {result.points} points rendered "
              f"(probes and test points; {result.renders - result.points} more rounds where noise or an unclear "
              f"split needed them, {result.samples} samples per pixel in all)")
    if result.resumed:
        print(f"bake.py: {result.rendered} render(s) by this run, {result.resumed} taken from journals or the previous "
              "bake's kept points")
    print(f"bake.py: {result.probe_count} probes in {result.seconds:.1f} s (placement {t['placement']:.2f} s, "
          f"render {t['render']:.2f} s, EXR write {t['write_exr']:.2f} s, projection {t['project']:.2f} s)")
    for f in result.files:
        print(f"bake.py: wrote {f}")


if __name__ == "__main__":
    main()
