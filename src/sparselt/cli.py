"""Command-line interface: ``sparselt <command> --help`` documents each command."""

from __future__ import annotations

import argparse
import os
import sys

# Constants live where they are defined; these modules import neither Mitsuba nor Dr.Jit.
from .experiments.compare import ComparisonConfig
from .rendering.acquire import NONFINITE_POLICIES, AcquisitionConfig
from .rendering.layout import KINDS
from .rendering.setup import DEFAULT_VARIANT, SUPPORTED_VARIANTS
from .storage.errors import caused_by_interrupt


def _number_list(convert, example):
    """argparse type for comma-separated numbers (``convert`` each), e.g. ``64,64,8,8``."""

    def parse(text):
        try:
            values = tuple(convert(part) for part in text.replace("x", ",").split(",") if part.strip())
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated numbers such as {example}, got {text!r}") from None
        if not values:
            raise argparse.ArgumentTypeError(f"expected at least one number, such as {example}")
        return values

    return parse


def _defaults(config):
    """``{name: default}`` of a configuration dataclass's fields, or of a function's keyword arguments: the one
    place a command's defaults live (the CLI reads them, never restates them)."""
    import dataclasses
    import inspect

    if dataclasses.is_dataclass(config):
        return {item.name: item.default for item in dataclasses.fields(config)
                if item.default is not dataclasses.MISSING}
    return {name: parameter.default for name, parameter in inspect.signature(config).parameters.items()
            if parameter.default is not inspect.Parameter.empty}


def _listed(values):
    return ",".join(map(str, values))


_shape = _number_list(int, "64,64,8,8")
_numbers = _number_list(float, "1,0.5,0.25")


def _reference_spp(text):
    """``--reference-spp``: a positive number of samples per pixel, or ``auto``."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected samples per pixel (a whole number) or 'auto', got {text!r}") from None


def _names(text):
    names = tuple(part.strip() for part in text.split(",") if part.strip())
    if not names:
        raise argparse.ArgumentTypeError(f"expected comma-separated method names, got {text!r}")
    return names


def _methods(text):
    from .fourier.integration import METHODS

    methods = tuple(part.strip() for part in text.split(",") if part.strip())
    unknown = [method for method in methods if method not in METHODS]
    if unknown or not methods:
        raise argparse.ArgumentTypeError(f"unknown integration method(s) {unknown or text!r}; choose from {','.join(METHODS)}")
    return methods


class _SceneParameters(argparse.Action):
    """``-D name=value``, repeatable: collects the pairs into a tuple sorted by name; a name given twice is an error."""

    def __call__(self, parser, namespace, text, option_string=None):
        name, separator, value = text.partition("=")
        name = name.strip()
        if not separator or not name:
            parser.error(f"-D takes name=value (Mitsuba's convention for a scene's $name parameters), got {text!r}")
        pairs = dict(getattr(namespace, self.dest) or ())
        if name in pairs and pairs[name] != value:
            parser.error(f"-D {name} is given twice ({pairs[name]!r} and {value!r}); give each parameter once")
        pairs[name] = value
        setattr(namespace, self.dest, tuple(sorted(pairs.items())))


class _MethodOption(argparse.Action):
    """``--option METHOD.NAME=VALUE``, repeatable: collects ``{METHOD: {NAME: VALUE}}`` (``*`` for every method)."""

    def __call__(self, parser, namespace, text, option_string=None):
        target, separator, value = text.partition("=")
        method, dot, name = target.strip().rpartition(".")
        if not separator or not dot or not method or not name:
            parser.error(f"--option takes METHOD.NAME=VALUE (for instance cosamp.gamma=0.5, or '*.gamma=0.5' for "
                         f"every method that declares gamma), got {text!r}")
        options = {key: dict(values) for key, values in (getattr(namespace, self.dest) or {}).items()}
        values = options.setdefault(method, {})
        key = name.replace("-", "_")
        if key in values and values[key] != value:
            parser.error(f"--option {method}.{name} is given twice ({values[key]!r} and {value!r}); give it once")
        values[key] = value
        setattr(namespace, self.dest, options)


#: Flags that each set one option for several methods at once, replaced by --option METHOD.NAME=VALUE (issue 19).
REMOVED_FLAGS = {"--gamma": "gamma", "--sparsity": "sparsity", "--alpha": "alpha", "--sft-snr": "snr",
                 "--map-spp": "map_spp", "--defensive": "defensive", "--guiding-mode": "mode",
                 "--thesis-faithful": None}


class _RemovedFlag(argparse.Action):
    def __call__(self, parser, namespace, values, option_string=None):
        name = REMOVED_FLAGS[option_string]
        if name is None:
            parser.error(f"{option_string} was removed: run the method cosamp-thesis (the thesis's procedure) instead")
        parser.error(f"{option_string} was replaced by --option METHOD.{name}=VALUE, one method at a time (or "
                     f"--option '*.{name}=VALUE' for every method of the run that declares {name}); "
                     f"'sparselt methods METHOD' lists a method's options")


def _add_plugin_option(parser):
    parser.add_argument("--plugin", action="append", default=[], metavar="MODULE",
                        help="import MODULE (on the Python path) first: its @register methods join the built-in ones "
                             "(repeatable; installed plug-ins of the entry-point group sparselt.methods load "
                             "without it)")


def _options_epilog():
    """The generated list of every registered method's options, for ``compare --help``."""
    import textwrap

    from .methods import method_class, method_names

    groups = {}
    for name in method_names():
        declared = method_class(name).Options.declared()
        summary = " ".join(f"{item.name}={item.default_description()}" for item in declared) or "(no options)"
        groups.setdefault(summary, []).append(name)
    lines = ["method options: --option METHOD.NAME=VALUE (repeatable; '*.NAME=VALUE' sets NAME for every method of",
             "the run that declares it). Defaults below; 'sparselt methods METHOD' gives ranges and help.", ""]
    for summary, names in groups.items():
        lines.append(f"  {', '.join(names)}:")
        lines += textwrap.wrap(summary, width=96, initial_indent="      ", subsequent_indent="      ")
    return "\n".join(lines)


def _add_scene_options(parser):
    parser.add_argument("-D", dest="parameters", action=_SceneParameters, default=(), metavar="NAME=VALUE",
                        help="value of the scene file's $NAME parameter, as Mitsuba's -D (repeatable; "
                             "part of the scene's identity)")


def _add_camera_options(parser):
    parser.add_argument("--aperture", type=float, default=None, help="switch the camera to a thin lens of this radius")
    parser.add_argument("--focus-distance", type=float, default=None,
                        help="focus distance of the thin lens (default: a thin-lens scene camera's own; with --aperture "
                             "on a pinhole camera, the distance at which the camera's central ray hits the scene, "
                             "or the camera's focus distance, 1000 unless the scene says otherwise, if it hits "
                             "nothing; the value used is recorded)")
    parser.add_argument("--variant", default=DEFAULT_VARIANT, choices=SUPPORTED_VARIANTS, help="Mitsuba variant (default: %(default)s)")


def build_parser():
    parser = argparse.ArgumentParser(prog="sparselt", description="Sparse reconstruction of multidimensional light transport signals.")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    scenes = commands.add_parser("scenes", help="list the built-in scenes", description="List the built-in scenes.")
    scenes.set_defaults(handler=_scenes)

    sample = commands.add_parser(
        "sample",
        help="sample a primary-sample-space signal",
        description="Sample a primary-sample-space signal: each cell is the mean of --spp jittered path samples. "
        "An interrupted run resumes when the same command is run again.",
    )
    sample.add_argument("--scene", required=True, help="built-in scene name (see 'sparselt scenes') or Mitsuba XML file")
    sample.add_argument("--kind", required=True, choices=KINDS, help="signal kind")
    group = sample.add_mutually_exclusive_group(required=True)
    group.add_argument("--shape", type=_shape, help="resolution of each axis, e.g. 64,64,8,8 (image plane first)")
    group.add_argument("--preset", choices=("thesis",), help="thesis resolutions: path 100x100x4^8, dof/indirect 250x250x16x16")
    defaults = _defaults(AcquisitionConfig)
    sample.add_argument("--spp", type=int, default=defaults["spp"], help="jittered samples per cell (default: %(default)s)")
    sample.add_argument("--seed", type=int, default=defaults["seed"], help="random seed (default: %(default)s)")
    sample.add_argument("--max-depth", type=int, default=defaults["max_depth"],
                        help="longest path, Mitsuba convention (default: %(default)s)")
    sample.add_argument("--out", required=True, help="signal folder to write")
    sample.add_argument("--overwrite", action="store_true", help="replace an existing signal")
    sample.add_argument("--verify", action="store_true",
                        help="check every chunk of a finished signal against its CRC-32 and sample the damaged ones "
                             "again (a rerun otherwise reads only the chunks whose files changed)")
    sample.add_argument("--nonfinite", choices=NONFINITE_POLICIES, default=defaults["nonfinite"],
                        help="NaN/Inf samples: stop with an error (default) or count them and use 0")
    sample.add_argument("--chunk-cells", type=int, default=None, help="cells per chunk (default: about 4M samples)")
    sample.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    _add_cluster_options(sample, "sample on")
    _add_camera_options(sample)
    _add_scene_options(sample)
    sample.set_defaults(handler=_sample)

    render = commands.add_parser(
        "render",
        help="render with Mitsuba's path integrator (the baseline)",
        description="Plain path tracing with Mitsuba's own path integrator; writes image.exr, image.png and render.json.",
    )
    from .experiments.render import render_reference

    defaults = _defaults(render_reference)
    render.add_argument("--scene", required=True, help="built-in scene name or Mitsuba XML file")
    render.add_argument("--spp", type=int, required=True, help="samples per pixel")
    render.add_argument("--max-depth", type=int, default=defaults["max_depth"],
                        help="longest path (default: %(default)s)")
    render.add_argument("--seed", type=int, default=defaults["seed"], help="sampler seed (default: %(default)s)")
    render.add_argument("--resolution", type=_shape, default=None, help="width,height (default: the scene's)")
    render.add_argument("--out", required=True, help="output folder")
    render.add_argument("--overwrite", action="store_true",
                        help="replace a folder holding another render (only the files sparselt wrote there)")
    _add_camera_options(render)
    _add_scene_options(render)
    render.set_defaults(handler=_render)

    analyze = commands.add_parser(
        "analyze",
        help="sparsity analysis: Gini tables and hard-thresholded SSIM",
        description="Gini index in both domains per gamma (Tables 5.1, 5.2, 7.1-7.3) and SSIM of hard-thresholded "
        "Fourier reconstructions against the signal's image (Figures 5.2-5.4, 7.1-7.6).",
    )
    analyze.add_argument("signal", help="signal folder")
    from .experiments.sparsity_analysis import analyze_signal

    defaults = _defaults(analyze_signal)
    analyze.add_argument("--gamma", type=_numbers, default=defaults["gammas"],
                         help=f"gamma mappings, comma separated "
                              f"(default: {_listed(f'{gamma:g}' for gamma in defaults['gammas'])})")
    analyze.add_argument("--fractions", type=_numbers, default=None,
                         help="fractions of Fourier coefficients kept, comma separated (default: 1e-5 .. 0.1)")
    analyze.add_argument("--out", required=True, help="output folder")
    analyze.add_argument("--overwrite", action="store_true",
                         help="replace a folder holding another analysis (only the files sparselt wrote there)")
    analyze.set_defaults(handler=_analyze)

    bench = commands.add_parser("bench", help="benchmarks that write figures", description="Benchmarks.")
    benches = bench.add_subparsers(dest="benchmark", required=True, metavar="BENCHMARK")
    bench_integrate = benches.add_parser(
        "integrate", help="integration methods (Figures 4.1, 4.2, Table 4.1)",
        description="Time and peak memory of the four Fourier integration methods on random sparse 4-D signals (thesis 4.3).")
    from .experiments.integration_benchmark import run_integration_benchmark

    defaults = _defaults(run_integration_benchmark)
    bench_integrate.add_argument("--sizes", type=_shape, default=defaults["sizes"],
                                 help=f"s values, N = s^4 (default: {_listed(defaults['sizes'])})")
    bench_integrate.add_argument("--methods", type=_methods, default=defaults["methods"],
                                 help=f"methods, comma separated (default: {_listed(defaults['methods'])})")
    bench_integrate.add_argument("--seed", type=int, default=defaults["seed"], help="random seed (default: %(default)s)")
    bench_integrate.add_argument("--repeats", type=int, default=defaults["repeats"],
                                 help="timed calls per measurement, best kept (default: %(default)s)")
    bench_integrate.add_argument("--out", required=True, help="output folder")
    bench_integrate.add_argument("--overwrite", action="store_true",
                                 help="replace a folder holding another benchmark (only the files sparselt wrote there)")
    bench_integrate.set_defaults(handler=_bench_integrate)

    compare = commands.add_parser(
        "compare", formatter_class=argparse.RawDescriptionHelpFormatter, epilog=_options_epilog(),
        help="equal-time comparison of methods against path tracing",
        description="Run methods at several budgets on one scene, kernels warmed first, and measure SSIM, relMSE "
        "(epsilon 0.01) and the luminance ratio against a cached path-traced reference. Writes results.csv, "
        "quality_vs_time.png, image_grid.png, table_8.md, images/ and compare.json; a rerun resumes.",
    )
    defaults = _defaults(ComparisonConfig)
    compare.add_argument("--scene", required=True, help="built-in scene name or Mitsuba XML file")
    compare.add_argument("--kind", required=True, choices=KINDS, help="signal kind")
    compare.add_argument("--shape", type=_shape, default=None,
                         help="signal grid of the kind, e.g. 250,250,16,16 (default: the scene film's width,height, "
                              "then 16 cells per lens or secondary-ray axis for dof and indirect, 4 per path-vertex "
                              "axis for path and path-indirect; recorded in compare.json)")
    compare.add_argument("--methods", type=_names, default=defaults["methods"],
                         help=f"comma-separated registered methods, each optionally a variant METHOD:NAME=VALUE[:...] "
                              f"(default: {_listed(defaults['methods'])}; 'sparselt methods' lists them)")
    compare.add_argument("--spp", type=_shape, default=defaults["spps"],
                         help=f"budgets in samples per pixel (default: {_listed(defaults['spps'])})")
    compare.add_argument("--seeds", type=_shape, default=defaults["seeds"],
                         help=f"seeds, comma separated; intervals and verdicts come from their spread "
                              f"(default: {_listed(defaults['seeds'])})")
    compare.add_argument("--timing-repeats", type=int, default=defaults["timing_repeats"],
                         help="runs of every cell; its time is the median (default: %(default)s)")
    compare.add_argument("--pt-ladder-max-spp", type=int, default=defaults["pt_ladder_max_spp"],
                         help="PT runs automatically at a doubling spp ladder until it passes every method's time, "
                              "up to this spp (default: %(default)s)")
    compare.add_argument("--resolution", type=_shape, default=None, help="output width,height (default: the shape's image axes)")
    compare.add_argument("--reference-spp", type=_reference_spp, default=defaults["reference_spp"],
                         help="reference samples per pixel, rendered in cached 64-spp passes (a rerun with more adds "
                              "passes), or 'auto': add passes until the reference's floor is under 10%% of the "
                              "smallest debiased relMSE among the judged cells (default: %(default)s)")
    compare.add_argument("--reference-minutes", type=float, default=None,
                         help="time limit of the reference's rendering in minutes (default: 10 with auto, none "
                              "otherwise)")
    compare.add_argument("--scheduler", default=None, metavar="ADDRESS",
                         help="a Dask scheduler (tcp://host:8786): the reference's passes render on its workers, "
                              "with the same bytes")
    compare.add_argument("--max-depth", type=int, default=defaults["max_depth"], help="longest path (default: %(default)s)")
    compare.add_argument("--option", dest="options", action=_MethodOption, default={}, metavar="METHOD.NAME=VALUE",
                         help="a method's option (repeatable; see the list below)")
    for flag in REMOVED_FLAGS:
        compare.add_argument(flag, nargs=0 if flag == "--thesis-faithful" else None, action=_RemovedFlag,
                             help=argparse.SUPPRESS)
    _add_plugin_option(compare)
    compare.add_argument("--caustic-mask", action="store_true",
                         help="also report relMSE inside a caustic mask: the pixels where caustic paths (light "
                              "reaching a diffuse surface through specular ones, L S+ D in Heckbert's notation, as "
                              "the renderer classifies its paths) carry over 30%% of the radiance; any scene, a "
                              "scene file included")
    compare.add_argument("--out", required=True, help="output folder (rerun to resume)")
    compare.add_argument("--overwrite", action="store_true",
                         help="replace a folder holding another comparison (only the files sparselt wrote there)")
    compare.add_argument("--no-progress", action="store_true", help="hide progress output")
    _add_camera_options(compare)
    _add_scene_options(compare)
    compare.set_defaults(handler=_compare)

    suite = commands.add_parser(
        "suite", help="every method over a suite of scenes, aggregated with intervals",
        description="Run an equal-time comparison per scene of a suite (a TOML file, or the built-in standard "
        "suite), and aggregate: suite.csv (every scene's summary), aggregate.csv (per method and budget the "
        "geometric mean over scenes of the speed-up over PT and of the relMSE ratio, with 95%% bootstrap "
        "intervals over scenes and seeds, verdict counts and the worst scene) and index.html with an "
        "interactive image viewer per scene. A rerun resumes.")
    suite.add_argument("file", nargs="?", default=None, help="a suite TOML file (see docs/suites.md)")
    suite.add_argument("--suite", dest="builtin", choices=("standard",), default=None,
                       help="the built-in suite instead of a file")
    suite.add_argument("--scale", choices=("quick", "default", "paper"), default=None,
                       help="the built-in suite's sizes: 128x128, 256x256 or 1024x576 (default: default)")
    suite.add_argument("--scenes", type=_names, default=None,
                       help="only these scenes of the built-in suite, comma separated")
    suite.add_argument("--methods", type=_names, default=None,
                       help="the built-in suite's methods instead of its scale's (each scene runs those that "
                            "support its kind)")
    suite.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="a Dask scheduler (tcp://host:8786) whose workers each hold one machine ('dask worker "
                            "ADDRESS --resources machine=1 --nthreads N'): references render across the cluster, "
                            "each scene's comparison on one machine")
    suite.add_argument("--out", required=True, help="output folder (rerun to resume)")
    suite.add_argument("--overwrite", action="store_true",
                       help="replace a folder holding another run (only the files sparselt wrote there)")
    suite.add_argument("--no-progress", action="store_true", help="hide progress output")
    _add_plugin_option(suite)
    suite.set_defaults(handler=_suite)

    table = commands.add_parser(
        "table61", help="the SFT on a rendered path space: Table 6.1 and Figures 6.1/6.2",
        description="Sparse Fourier Transform of a rendered path-space signal through the renderer as its oracle "
                    "(thesis 6.1): samples per alpha beside the thesis's Table 6.1, image quality against a reference "
                    "and against path tracing at equal samples and equal time, and how compressible the signal is.")
    from .experiments.sft_path_space import Table61Config

    defaults = _defaults(Table61Config)
    table.add_argument("--scene", required=True, help="built-in scene name or Mitsuba XML file")
    table.add_argument("--kind", default=defaults["kind"], choices=KINDS, help="signal kind (default: %(default)s)")
    table.add_argument("--shape", type=_shape, default=defaults["shape"],
                       help=f"grid (default: the thesis's {_listed(defaults['shape'])})")
    table.add_argument("--alpha", type=_numbers, default=defaults["alphas"],
                       help=f"buckets per coefficient (default {_listed(f'{alpha:g}' for alpha in defaults['alphas'])})")
    table.add_argument("--spp", type=int, default=defaults["spp"],
                       help="path samples per lattice point (default: %(default)s)")
    table.add_argument("--noise-spp", type=_shape, default=defaults["noise_spps"],
                       help=f"also run the first alpha at these samples per point "
                            f"(default: {_listed(defaults['noise_spps'])})")
    table.add_argument("--sparsity", type=int, default=defaults["sparsity"], help="K (default N/10^4, as the thesis)")
    table.add_argument("--snr", type=float, default=defaults["snr"],
                       help="SNR in dB the SFT assumes (default: %(default)s)")
    table.add_argument("--seed", type=int, default=defaults["seed"], help="seed (default: %(default)s)")
    table.add_argument("--reference-spp", type=int, default=defaults["reference_spp"],
                       help="reference samples per pixel (default: %(default)s)")
    table.add_argument("--max-depth", type=int, default=defaults["max_depth"], help="longest path (default: %(default)s)")
    table.add_argument("--compressibility-shape", type=_shape, default=None,
                       help="grid fully sampled to measure compressibility (default: image /4, other axes /2)")
    table.add_argument("--out", required=True, help="output folder (rerun to resume)")
    table.add_argument("--no-progress", action="store_true", help="hide progress output")
    _add_camera_options(table)
    _add_scene_options(table)
    table.set_defaults(handler=_table61)

    reproduce = commands.add_parser(
        "reproduce", help="the thesis's experiments as one HTML page, the thesis's numbers beside ours",
        description="Run the experiments of a thesis chapter (resumable) and write DIR/index.html: each thesis "
                    "table beside our measurements, figures, verdicts, wall times and provenance.")
    reproduce.add_argument("--chapter", default="all", help="4, 5, 6, 7, 8 or all (default: all reproduced so far)")
    reproduce.add_argument("--scale", default="quick",
                           help="tiny (a minute: the pipeline only), quick (minutes), medium (1-2 h on 2 cores, the "
                                "thesis's 4-D sizes) or thesis (the thesis's sizes; about a day)")
    reproduce.add_argument("--out", required=True, help="output folder (rerun to resume)")
    reproduce.add_argument("--overwrite", action="store_true",
                           help="replace a folder holding the other scale (only the files sparselt wrote there)")
    reproduce.add_argument("--no-progress", action="store_true", help="hide progress output")
    reproduce.add_argument("--methods", type=_names, default=(),
                           help="more rows of chapter 8's equal-time comparison: method names or variants "
                                "METHOD:NAME=VALUE[:...], comma separated, each a row named as written")
    _add_plugin_option(reproduce)
    reproduce.set_defaults(handler=_reproduce)

    methods = commands.add_parser(
        "methods", help="list the comparison methods, or describe some",
        description="Without names: every registered comparison method, the kinds it supports and what it does. "
                    "With names: each one's kinds, roles, source and every option with its type, default, "
                    "allowed range and thesis section.")
    methods.add_argument("names", nargs="*", metavar="METHOD", help="methods to describe")
    _add_plugin_option(methods)
    methods.set_defaults(handler=_list_methods)

    show = commands.add_parser("show", help="pictures of a signal", description="Write the integrated image and 2-D slices of a signal as PNGs.")
    show.add_argument("signal", help="signal folder")
    show.add_argument("--out", required=True, help="output folder")
    show.add_argument("--overwrite", action="store_true",
                      help="replace a folder holding pictures of another signal (only the files sparselt wrote there)")
    _add_cluster_options(show, "compute the integrated image on")
    show.set_defaults(handler=_show)
    return parser


def _scenes(arguments):
    from .rendering.scenes import get_scene, scene_names

    for name in scene_names():
        spec = get_scene(name)
        lens = "thin lens" if spec.camera is not None and spec.camera.thin_lens else "pinhole"
        print(f"{name:18s} {lens:9s} {spec.description}")
    return 0


def _add_cluster_options(parser, what):
    cluster = parser.add_mutually_exclusive_group()
    cluster.add_argument("--workers", type=int, default=None, help=f"{what} a local Dask cluster of this many worker processes")
    cluster.add_argument("--scheduler", default=None,
                         help=f"{what} an existing Dask cluster (scheduler address); its workers must reach the signal")


def _sample(arguments):
    from .rendering.acquire import THESIS_PRESETS, AcquisitionConfig, acquire_signal, complete_signal

    shape = THESIS_PRESETS[arguments.kind] if arguments.preset == "thesis" else arguments.shape
    config = AcquisitionConfig(
        scene=arguments.scene,
        kind=arguments.kind,
        shape=tuple(shape),
        spp=arguments.spp,
        seed=arguments.seed,
        max_depth=arguments.max_depth,
        aperture=arguments.aperture,
        focus_distance=arguments.focus_distance,
        variant=arguments.variant,
        nonfinite=arguments.nonfinite,
        scene_parameters=arguments.parameters,
    )
    if not arguments.overwrite:  # a rerun of a finished command: nothing to do, and it says so
        signal = complete_signal(config, arguments.out, verify=arguments.verify)
        if signal is not None:
            checked = ("every chunk matches its CRC-32" if arguments.verify
                       else "no chunk changed since it was written; --verify reads every chunk")
            print(f"{arguments.out} is complete: {signal.kind} signal, axes {', '.join(signal.axes)}, shape "
                  f"{signal.shape}; nothing to do ({checked})")
            return 0
    signal = acquire_signal(config, arguments.out, overwrite=arguments.overwrite,
                            progress=not arguments.no_progress, chunk_cells=arguments.chunk_cells,
                            workers=arguments.workers, scheduler=arguments.scheduler, verify=arguments.verify)
    print(f"wrote {arguments.out}: {signal.kind} signal, axes {', '.join(signal.axes)}, shape {signal.shape}, "
          f"{signal.meta.get('sampling_seconds', 0):.1f} s of sampling")
    return 0


def _render(arguments):
    from .experiments.render import render_reference

    resolution = arguments.resolution
    if resolution is not None and len(resolution) != 2:
        raise ValueError(f"--resolution takes width,height, got {resolution}")
    _, record = render_reference(arguments.scene, arguments.out, spp=arguments.spp, max_depth=arguments.max_depth,
                                 seed=arguments.seed, resolution=resolution, aperture=arguments.aperture,
                                 focus_distance=arguments.focus_distance, variant=arguments.variant,
                                 overwrite=arguments.overwrite, parameters=arguments.parameters)
    print(f"wrote {arguments.out}: {record['resolution'][0]}x{record['resolution'][1]} at {record['spp']} spp "
          f"in {record['seconds']:.2f} s ({record['samples_per_second'] / 1e6:.2f} M samples/s)")
    return 0


def _analyze(arguments):
    from .experiments.sparsity_analysis import DEFAULT_FRACTIONS, analyze_signal
    from .signal import load_signal

    signal = load_signal(arguments.signal)
    result = analyze_signal(signal, arguments.out, gammas=arguments.gamma, fractions=arguments.fractions or DEFAULT_FRACTIONS,
                            overwrite=arguments.overwrite)
    print(result["gamma_table"])
    print(f"wrote {arguments.out}")
    return 0


def _bench_integrate(arguments):
    from .experiments.integration_benchmark import run_integration_benchmark

    run_integration_benchmark(arguments.out, sizes=tuple(arguments.sizes), methods=arguments.methods, seed=arguments.seed,
                              repeats=arguments.repeats, overwrite=arguments.overwrite)
    return 0


def _compare(arguments):
    from .experiments.compare import ComparisonConfig, compare

    config = ComparisonConfig(
        scene=arguments.scene, kind=arguments.kind, shape=tuple(arguments.shape) if arguments.shape else None,
        methods=tuple(arguments.methods),
        spps=tuple(arguments.spp), seeds=tuple(arguments.seeds),
        resolution=tuple(arguments.resolution) if arguments.resolution else None,
        reference_spp=arguments.reference_spp, reference_minutes=arguments.reference_minutes,
        max_depth=arguments.max_depth, aperture=arguments.aperture,
        focus_distance=arguments.focus_distance, options=arguments.options, timing_repeats=arguments.timing_repeats,
        pt_ladder_max_spp=arguments.pt_ladder_max_spp, caustic_mask=arguments.caustic_mask,
        variant=arguments.variant, scene_parameters=arguments.parameters)
    result = compare(config, arguments.out, overwrite=arguments.overwrite, progress=not arguments.no_progress,
                     scheduler=arguments.scheduler)
    print(result.table())
    print(f"relMSE epsilon 0.01; harness overhead {100 * result.overhead_fraction:.1f}% of the run; wrote {arguments.out}")
    return 0


def _suite(arguments):
    from .experiments.standard_suite import standard_suite
    from .experiments.suite import run_suite
    from .experiments.suite_config import read_suite

    if (arguments.file is None) == (arguments.builtin is None):
        raise ValueError("give a suite file or --suite standard (one of them)")
    if arguments.file is not None and (arguments.scale or arguments.scenes or arguments.methods):
        raise ValueError("--scale, --scenes and --methods choose the built-in suite's settings; a suite file "
                         "states its own (edit the file)")
    if arguments.file is not None:
        config = read_suite(arguments.file)
    else:
        config = standard_suite(arguments.scale or "default", methods=arguments.methods, scenes=arguments.scenes)
    result = run_suite(config, arguments.out, overwrite=arguments.overwrite, progress=not arguments.no_progress,
                       scheduler=arguments.scheduler)
    print(result.table())
    print(f"wrote {arguments.out} in {result.seconds:.0f} s; open {os.path.join(os.path.abspath(arguments.out), 'index.html')}")
    if result.not_compared:
        for name, message in result.not_compared.items():
            print(f"sparselt suite: error: scene {name!r} could not be compared: {message}", file=sys.stderr)
        recorded = len(result.not_compared) - len(result.crashed)
        print(f"sparselt suite: {len(result.not_compared)} of {len(config.scenes)} scenes could not be compared; "
              "the others are aggregated without them"
              + (" (a suite without the scenes that could not be compared, or with their files changed, is another "
                 "run: give it another --out)" if recorded else "")
              + (f"; {len(result.crashed)} crashed and a rerun of the same command tries "
                 f"{'them' if len(result.crashed) > 1 else 'it'} again" if result.crashed else ""), file=sys.stderr)
        return 2
    return 0


def _table61(arguments):
    from .experiments.sft_path_space import Table61Config, run_table61

    config = Table61Config(scene=arguments.scene, shape=tuple(arguments.shape), kind=arguments.kind,
                           alphas=tuple(arguments.alpha), spp=arguments.spp, noise_spps=tuple(arguments.noise_spp),
                           sparsity=arguments.sparsity, snr=arguments.snr, seed=arguments.seed,
                           reference_spp=arguments.reference_spp, max_depth=arguments.max_depth,
                           compressibility_shape=tuple(arguments.compressibility_shape)
                           if arguments.compressibility_shape else None, scene_parameters=arguments.parameters,
                           aperture=arguments.aperture, focus_distance=arguments.focus_distance,
                           variant=arguments.variant)
    run_table61(config, arguments.out, progress=not arguments.no_progress)
    with open(os.path.join(arguments.out, "table_6_1.md"), encoding="utf-8") as handle:
        print(handle.read())
    print(f"wrote {arguments.out}")
    return 0


def _reproduce(arguments):
    from .experiments.reproduce import reproduce

    path = reproduce(arguments.chapter, arguments.scale, arguments.out, progress=not arguments.no_progress,
                     overwrite=arguments.overwrite, plugins=tuple(arguments.plugin),
                     methods=tuple(arguments.methods))
    print(f"open {os.path.abspath(path)}")
    return 0


def _list_methods(arguments):
    from .methods import method_class, method_names

    if not arguments.names:
        for name in method_names():
            method = method_class(name)
            print(f"{name:16s} {','.join(method.kinds):22s} {method.description}")
        print("\n'sparselt methods METHOD' describes a method and its options")
        return 0
    for index, name in enumerate(arguments.names):
        print(("\n" if index else "") + describe_method(method_class(name)))
    return 0


def describe_method(method):
    """A method's description, kinds, roles, source and options, as ``sparselt methods NAME`` prints it."""
    import textwrap

    from .methods.options import describe_options
    from .methods.registry import method_source

    roles = method.roles()
    lines = [f"{method.name}: {method.description}",
             f"  kinds: {', '.join(method.kinds)}",
             f"  family: {roles['family']}; baseline: {'yes' if roles['baseline'] else 'no'}; thesis procedure: "
             f"{'yes' if roles['thesis_procedure'] else 'no'}",
             f"  source: {method_source(method.name)}"]
    described = describe_options(method.Options)
    if not described:
        lines.append("  options: none")
        return "\n".join(lines)
    lines.append(f"  options (--option {method.name}.NAME=VALUE):")
    width = max(len(row[0]) for row in described)
    for name, kind, default, allowed, section, help_text in described:
        where = f"; thesis {section}" if section else ""
        lines.append(f"    {name:{width}s}  {kind:5s}  default {default}; {allowed}{where}")
        lines += textwrap.wrap(help_text, width=96, initial_indent=" " * (width + 6), subsequent_indent=" " * (width + 6))
    return "\n".join(lines)


def _show(arguments):
    from .signal import load_signal
    from .visualize import show_signal

    signal = load_signal(arguments.signal)
    if arguments.workers is None and arguments.scheduler is None:
        written = show_signal(signal, arguments.out, overwrite=arguments.overwrite)
    else:
        from .distributed import dask_client

        with dask_client(workers=arguments.workers, scheduler=arguments.scheduler) as client:
            written = show_signal(signal, arguments.out, client=client, overwrite=arguments.overwrite)
    for path in written:
        print(f"wrote {path}")
    return 0


def _describe(error):
    """A one-line message for an error; operating-system errors say what failed on which path
    (:func:`sparselt.storage.errors.os_error_reason`) and what to do. An error Dr.Jit wraps ("error while
    performing a custom differentiable operation. (see above)", as ``mi.render`` raises it) is described by the
    error it wraps: "above" is a traceback the user does not see."""
    while "(see above)" in str(error) and isinstance(error.__cause__, Exception):
        error = error.__cause__
    if isinstance(error, OSError) and error.strerror:  # raised by the operating system, not by sparselt
        import errno

        from .storage.errors import NO_SPACE_ERRORS, os_error_reason

        fix = ("free some space, or choose another disk" if error.errno in NO_SPACE_ERRORS
               else "choose a folder on a writable disk" if error.errno == errno.EROFS else "")
        return os_error_reason(error) + (f"; {fix}" if fix else "")
    return str(error)


def _plugins_named(argv):
    """The ``--plugin MODULE`` values of a command line, read before the parser is built (its help lists them)."""
    modules = []
    for index, word in enumerate(argv):
        if word == "--plugin" and index + 1 < len(argv):
            modules.append(argv[index + 1])
        elif word.startswith("--plugin="):
            modules.append(word.split("=", 1)[1])
    return modules


def report_crashes():
    """Have a crash inside native code (the renderer, a numba kernel) print where Python was before the process
    dies: Python's ``faulthandler`` on standard error, every thread's stack.

    A segmentation fault in a Dr.Jit worker thread ended a suite run with no word at all (issue 37, sixteenth
    session: Mitsuba reading past a curve's segment table); with this, standard error names the method and the
    step (``comparison_cells._repeat``, ``run_timed``, the method's ``run``, the renderer's call).
    """
    import faulthandler

    if not faulthandler.is_enabled():
        try:
            faulthandler.enable(file=sys.stderr, all_threads=True)
        except (AttributeError, ValueError, OSError):  # no usable file descriptor behind sys.stderr
            pass


def main(argv=None):
    from .provenance import record_command

    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        from .methods import load_plugins

        load_plugins(_plugins_named(argv))  # installed (entry-point) plug-ins too
    except ValueError as error:
        command = next((word for word in argv if not word.startswith("-")), "")
        print(f"sparselt{' ' + command if command else ''}: error: {error}", file=sys.stderr)
        return 2
    parser = build_parser()
    arguments = parser.parse_args(argv)
    record_command(["sparselt"] + argv)
    report_crashes()
    try:
        try:
            return arguments.handler(arguments)
        except (ValueError, TypeError, RuntimeError, OSError) as error:
            # Ctrl-C during a Mitsuba render cancels the render (a RuntimeError) and then re-raises the signal:
            # Python's pending KeyboardInterrupt fires here, on the first bytecode, before the error is reported.
            # A Ctrl-C that lands in mi.render's Python part instead is wrapped by drjit.custom into a RuntimeError
            # whose cause is the KeyboardInterrupt: that is an interruption too, not an error.
            if caused_by_interrupt(error):
                raise KeyboardInterrupt from error
            message = _describe(error)
            print(f"sparselt {arguments.command}: error: {message}", file=sys.stderr)
            return 2
    except KeyboardInterrupt:
        done = "finished chunks are kept" if arguments.command == "sample" else "finished work is kept"
        print(f"sparselt {arguments.command}: interrupted; {done}: rerun the same command to resume", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
