"""Pins the CPU-dependent arithmetic of the reference side (reference venv only).

Import this module before numpy. The reference environments compute their controller
with numpy: its ufuncs pick SIMD loops by CPU at run time (AVX-512 loops, SVML-based for
exp, log, arctan2, arccos, arcsin, tan, power, on CPUs that have AVX-512; the C library's
functions elsewhere) and its linear algebra (np.linalg.inv, pinv, det, matmul) goes
through OpenBLAS, whose kernels are also picked by CPU (SkylakeX on AVX-512 CPUs,
Haswell on AVX2 ones). Either choice changes the last bits of the controller's torques,
and a contact-rich replay turns last bits into a different success step: measured on one
machine, click_mouse succeeds at 529 or 530 and bimanual_assembly at 1016, 1035, 1044 or
not at all, depending on these two choices alone (docs/reference-parity.md).

So the parity tests run the reference under a named setting, the same bits on every CPU
that has it. `DEXJOCO_REFERENCE_ARITHMETIC` picks it (default `avx2`):

- `avx2`: numpy without its AVX-512 loops, OpenBLAS's Haswell kernels: what every x86-64
  CPU with AVX2 and FMA (Intel since 2013, AMD since 2015) computes without AVX-512.
- `sandybridge`: numpy without its AVX-512 loops, OpenBLAS's Sandy Bridge (AVX) kernels.
- `baseline`: numpy's baseline loops only (no dispatch), OpenBLAS's Prescott (SSE3)
  kernels: the same on every x86-64 CPU.
- `avx512`: numpy's AVX-512 loops and OpenBLAS's SkylakeX kernels (AVX-512 CPUs only).
- `avx512-numpy`: numpy's AVX-512 loops, OpenBLAS's Haswell kernels (AVX-512 CPUs only).
- `avx512-blas`: numpy without its AVX-512 loops, OpenBLAS's SkylakeX kernels (AVX-512
  CPUs only).
- `native`: whatever the machine and the caller's environment pick.

What is not pinned: the C library's libm (glibc picks FMA variants of sin, exp... on
CPUs with FMA), which MuJoCo, numpy's non-SIMD loops and our Rust code all call alike.
"""

from __future__ import annotations

import os
import sys

VARIABLE = "DEXJOCO_REFERENCE_ARITHMETIC"
DEFAULT = "avx2"

# numpy 1.26's dispatched x86 features above its baseline (SSE, SSE2, SSE3). Naming one
# the CPU lacks is harmless.
_AVX512 = "AVX512F AVX512CD AVX512_KNL AVX512_KNM AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL AVX512_SPR"
_ALL = "SSSE3 SSE41 POPCNT SSE42 AVX F16C FMA3 AVX2 " + _AVX512

# name: (numpy features switched off, OpenBLAS core, CPU flags it needs)
SETTINGS = {
    "avx2": (_AVX512, "Haswell", ("avx2", "fma")),
    "sandybridge": (_AVX512, "Sandybridge", ("avx",)),
    "baseline": (_ALL, "Prescott", ()),
    "avx512": ("", "SkylakeX", ("avx512f", "avx512bw", "avx512vl", "avx512dq")),
    "avx512-numpy": ("", "Haswell", ("avx512f", "avx512bw", "avx512vl", "avx512dq")),
    "avx512-blas": (_AVX512, "SkylakeX", ("avx512f", "avx512bw", "avx512vl", "avx512dq")),
}


def cpu_flags() -> set[str]:
    """The CPU's feature flags (/proc/cpuinfo; empty where it cannot be read)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def pin() -> str:
    """Applies the setting `$DEXJOCO_REFERENCE_ARITHMETIC` names to this process's
    environment (numpy and OpenBLAS read it when numpy is first imported); returns its
    name. Exits with a message for an unknown name or one this CPU cannot run."""
    name = os.environ.get(VARIABLE, DEFAULT) or DEFAULT
    if name == "native":
        return name
    if name not in SETTINGS:
        sys.exit(f"error: ${VARIABLE}={name!r} is not one of {', '.join([*SETTINGS, 'native'])}")
    if "numpy" in sys.modules:
        sys.exit("error: reference_arithmetic must be imported before numpy")
    off, core, needs = SETTINGS[name]
    missing = [f for f in needs if f not in cpu_flags()]
    if missing:
        sys.exit(
            f"error: ${VARIABLE}={name} needs CPU features this machine lacks: {', '.join(missing)} "
            f"(run the parity tests with another setting: {', '.join(SETTINGS)})"
        )
    os.environ["NPY_DISABLE_CPU_FEATURES"] = off
    os.environ["OPENBLAS_CORETYPE"] = core
    return name


NAME = pin()
