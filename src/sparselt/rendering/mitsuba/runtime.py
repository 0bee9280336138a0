"""Starting Mitsuba 3 and Dr.Jit: the variants, the LLVM library, threads and versions.

Nothing here imports Mitsuba or Dr.Jit when the module is imported, so the
command line reads :data:`DEFAULT_VARIANT` and :data:`SUPPORTED_VARIANTS`
without starting the renderer. :func:`initialize` imports both; every other
module of :mod:`sparselt.rendering.mitsuba` reaches them through
:func:`modules`.

Notes
-----
Dr.Jit's LLVM backend needs LLVM >= 17 (older versions fail with
"Cannot select: fminimum"). :func:`find_llvm_library` locates a suitable
``libLLVM`` before Dr.Jit is imported and exports ``DRJIT_LIBLLVM_PATH``.
"""

from __future__ import annotations

import glob
import os
import re
import sys

#: Mitsuba variants sparselt runs on, and the default (the CPU's LLVM backend).
SUPPORTED_VARIANTS = ("llvm_ad_rgb", "cuda_ad_rgb")
DEFAULT_VARIANT = "llvm_ad_rgb"
#: Oldest libLLVM Dr.Jit's LLVM backend runs on.
MINIMUM_LLVM = 17

_LLVM_HELP = (
    "Dr.Jit's LLVM backend needs libLLVM {minimum} or newer. On Debian 12 run "
    "'apt-get install -y libllvm19' (the Makefile's bootstrap does this), or "
    "'pip install karellen-llvm-core' and set DRJIT_LIBLLVM_PATH to its libLLVM.so."
)

#: The ``mitsuba`` and ``drjit`` modules once :func:`initialize` has run, else ``None``.
mi = None
dr = None


def _llvm_version(path):
    match = re.search(r"libLLVM(?:-|\.so\.)(\d+)", os.path.basename(path))
    return int(match.group(1)) if match else None


def find_llvm_library():
    """Path of the newest libLLVM >= 17 on this machine, or ``None``.

    Looks in the system library folders, in ``/usr/lib/llvm-*/lib`` and in the
    running Python's prefix (where ``karellen-llvm-core`` installs).
    """
    patterns = [
        "/usr/lib/x86_64-linux-gnu/libLLVM*.so*",
        "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
        "/usr/lib/llvm-*/lib/libLLVM*.so*",
        "/usr/lib64/libLLVM*.so*",
        "/usr/local/lib/libLLVM*.so*",
        os.path.join(sys.prefix, "lib", "python*", "site-packages", "**", "libLLVM*.so*"),
    ]
    candidates = []
    for pattern in patterns:
        for path in glob.glob(pattern, recursive=True):
            version = _llvm_version(path)
            if version is not None and version >= MINIMUM_LLVM and os.path.isfile(path):
                candidates.append((version, path))
    return max(candidates)[1] if candidates else None


def initialize(variant=None):
    """Import Mitsuba with the requested variant and return the module.

    Parameters
    ----------
    variant : {'llvm_ad_rgb', 'cuda_ad_rgb'}, optional
        Default ``llvm_ad_rgb`` (CPU), or the environment's ``SPARSELT_VARIANT``.
        ``cuda_ad_rgb`` needs an NVIDIA GPU.

    Raises
    ------
    ValueError
        Unsupported variant name.
    RuntimeError
        No usable LLVM (with the command that fixes it) or no CUDA device.
    """
    global mi, dr
    variant = variant or os.environ.get("SPARSELT_VARIANT", DEFAULT_VARIANT)
    if variant not in SUPPORTED_VARIANTS:
        raise ValueError(f"unsupported Mitsuba variant {variant!r}; choose one of {', '.join(SUPPORTED_VARIANTS)}")
    if variant.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ and dr is None:
        library = find_llvm_library()
        if library is None:
            raise RuntimeError("no libLLVM >= %d found. " % MINIMUM_LLVM + _LLVM_HELP.format(minimum=MINIMUM_LLVM))
        os.environ["DRJIT_LIBLLVM_PATH"] = library
    try:
        import drjit as drjit_module
        import mitsuba as mitsuba_module

        mitsuba_module.set_variant(variant)
        probe = mitsuba_module.Float(1.0, 2.0) * 2.0
        drjit_module.eval(probe)
    except Exception as error:  # noqa: BLE001  (re-raised with the fix)
        if variant.startswith("cuda"):
            raise RuntimeError(f"Mitsuba variant {variant!r} is unavailable ({error}); is there an NVIDIA GPU?") \
                from error
        raise RuntimeError(f"Mitsuba could not start its LLVM backend ({error}). "
                           + _LLVM_HELP.format(minimum=MINIMUM_LLVM)) from error
    mi, dr = mitsuba_module, drjit_module
    return mi


def modules():
    """``(mitsuba, drjit)``, started with the default variant by :func:`initialize` if nothing started them yet."""
    if mi is None:
        initialize()
    return mi, dr


def set_thread_count(count):
    """Size Dr.Jit's CPU thread pool (a Dask worker takes its share of the machine's cores)."""
    import drjit as drjit_module

    if drjit_module.thread_count() != int(count):
        drjit_module.set_thread_count(int(count))


def thread_count():
    """The size of Dr.Jit's CPU thread pool (the threads a render uses)."""
    import drjit as drjit_module

    return int(drjit_module.thread_count())


def versions():
    """Versions of the rendering stack, for provenance records."""
    import drjit as drjit_module
    import mitsuba as mitsuba_module

    return {"mitsuba": mitsuba_module.__version__, "drjit": drjit_module.__version__}
