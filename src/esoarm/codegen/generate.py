"""C99 source for a scenario's observer and controller as designed, one generator for every kind.

The generated translation unit is the sampled-data loop's steps 2, 3 and 5
(:mod:`esoarm.engines.loop`) for one joint, as
:class:`esoarm.hardware.host_control.DeploymentController` steps them:

    first sample: initialize observer and controller from y_0
    ẑ_k = estimate(z_k, y_k)                       (observer kind's C)
    u_k = sat(control(ẑ_k, y_k, reference(k)))      (controller kind's C, ±torque_limit)
    u_k, drive_k, duty_k = actuate(u_k, ẑ2_k)       (motor: torque -> duty)
    z_{k+1} = advance(z_k, ẑ_k, y_k, v_k)           (v_k: the plant kind's observer input)

Each kind provides its C once, beside its Python step: the module attribute
``C_SOURCE`` names a ``.c`` file in the kind's package (``observers/linear.c``
beside ``observers/linear.py``) that reads the kind's design vector (without its
CODE) as ``OBS_P`` / ``CTL_P`` with the Python step's indices, and defines the
size of its C state, ``OBS_NZ`` / ``CTL_NC``, as an integer or an expression of
``OBS_N`` / ``CTL_N``, the Python state's length for the design at hand (the
cascade ESO: ``2 * OBS_N``, the states of its p levels and their carried
errors).  The generator emits the design vectors and those lengths as
constants, the reference trajectory of :mod:`esoarm.reference`, the actuator
(:file:`actuator.c`) and the step; a kind without ``C_SOURCE`` is refused
(:class:`CodegenError`).  No heap, no host code: ``esoarm_controller.h`` /
``esoarm_controller.c`` compile with any C99 compiler and ``<math.h>``.

Precision: ``float64`` is the Python reference's arithmetic (on the host the
same operations in the same order); ``float32`` evaluates the same expressions
in single precision.  ``compensated`` (float32 default) sums the observer's
increments with their rounding error carried to the next sample (Kahan), which
keeps the increments Ts·(…) that fall below half an ulp of z (small ε, high
rates) from being lost (see docs/on-the-chip.md).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np

from esoarm import __version__
from esoarm.contract import Kind
from esoarm.kinds import Kinds, kinds_of
from esoarm.plants.actuator import actuator_vector
from esoarm.reference import Multisine, QuinticSteps

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["PRECISIONS", "TARGETS", "CodegenError", "Generated", "c_source", "generate",
           "scenario_hash", "write_sources"]

#: Targets and the precisions their compilers offer (avr-gcc's double is 32 bits).
TARGETS: dict[str, tuple[str, ...]] = {
    "host": ("float64", "float32"),
    "avr": ("float32",),
    "cortex-m4": ("float32", "float64"),
}
PRECISIONS = ("float32", "float64")

HEADER = "esoarm_controller.h"
SOURCE = "esoarm_controller.c"


class CodegenError(ValueError):
    """A scenario, kind, target or precision the generator cannot serve (one line)."""


def c_source(module: Kind | ModuleType) -> str | None:
    """The C of a kind module (its ``C_SOURCE`` file beside it), None if it has none.

    Parameters
    ----------
    module : module
        A registered kind (:mod:`esoarm.kinds`).

    Returns
    -------
    str or None
        The text of the ``.c`` file named by the module's ``C_SOURCE``.
    """
    name = getattr(module, "C_SOURCE", None)
    if not name:
        return None
    package = module.__name__.rpartition(".")[0]
    return (resources.files(package) / name).read_text(encoding="utf-8")


def scenario_hash(scn: Scenario) -> str:
    """First 16 hex digits of the SHA-256 of the resolved scenario's JSON.

    Parameters
    ----------
    scn : Scenario
        A validated scenario (with its overrides).

    Returns
    -------
    str
        16 lower-case hex digits; the same for the same resolved scenario.
    """
    return hashlib.sha256(scn.model_dump_json().encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Generated:
    """The generated sources of one scenario, target and precision.

    Attributes
    ----------
    header, source : str
        ``esoarm_controller.h`` and ``esoarm_controller.c``.
    scenario : str
        Scenario name.
    digest : str
        :func:`scenario_hash` of the scenario.
    target, precision : str
        As requested.
    compensated : bool
        The observer sums its increments with compensation.
    """

    header: str
    source: str
    scenario: str
    digest: str
    target: str
    precision: str
    compensated: bool


def _literal(x: float) -> str:
    """A C literal that parses to the double ``x`` exactly (wrapped in R(): the precision)."""
    if not np.isfinite(x):
        raise CodegenError(f"a design value is not finite ({x!r}): nothing to generate")
    text = repr(float(x))
    if "e" not in text and "." not in text:
        text += ".0"
    return f"R({text})"


def _array(name: str, values: np.ndarray | list[float]) -> str:
    items = ", ".join(_literal(float(v)) for v in values)
    return f"static const esoarm_real {name}[{max(len(values), 1)}] = {{{items or 'R(0.0)'}}};\n"


def _first_sample(ts: float, bound: float) -> int:
    """The first k ≥ 0 with k·Ts ≥ bound, in float64 as the Python reference tests it."""
    k = max(0, math.ceil(bound / ts))
    while k > 0 and (k - 1) * ts >= bound:
        k -= 1
    while k * ts < bound:
        k += 1
    return k


def _reference_c(scn: Scenario) -> str:
    """``ref_eval(k, out)``: θd, θ̇d, θ̈d at t_k = k·Ts, as in :mod:`esoarm.reference`."""
    ref = scn.reference
    head = ("/* The reference at t_k = k Ts (esoarm.reference). */\n"
            "static void ref_eval(uint32_t k, esoarm_real out[3])\n{\n"
            "    esoarm_real t = (esoarm_real)k * REF_TS;\n")
    if isinstance(ref, QuinticSteps):
        moves = [float(v) for m in ref.moves for v in m]
        inverse = [float(v) for _, dur, _ in ref.moves for v in (1.0 / dur, 1.0 / (dur * dur))]
        # float32: which samples fall before, in and after each move are decided on the
        # sample index k, with the Python reference's own tests on t_k = k·Ts (float64), and
        # the time into the move is tau = (k − K_start)·Ts + F with F = K_start·Ts − t0, so
        # that tau keeps float32's relative precision within the move instead of losing it
        # to t (ulp(20 s) = 1.9e-6 s; measured: the cascade ESO at ε = 0.01 s, 1 kHz went
        # from 7.1e-4 to 1.1e-4 N·m of |Δu| with this alone)
        ts = scn.sample_time
        starts = [_first_sample(ts, t0) for t0, _, _ in ref.moves]
        ends = [_first_sample(ts, t0 + dur) for t0, dur, _ in ref.moves]
        offsets = [k * ts - t0 for (t0, _, _), k in zip(ref.moves, starts, strict=True)]
        return (_array("REF_MOVES", moves) + _array("REF_INVERSE", inverse)
                + "#if ESOARM_MOVE_TIME\n"
                + f"static const int32_t REF_KSTART[{len(starts)}] = "
                + "{" + ", ".join(f"{k}L" for k in starts) + "};\n"
                + f"static const int32_t REF_KEND[{len(ends)}] = "
                + "{" + ", ".join(f"{k}L" for k in ends) + "};\n"
                + _array("REF_OFFSET", offsets)
                + "#endif\n"
                + f"#define REF_NMOVES {len(ref.moves)}\n"
                + head.replace("    esoarm_real t = (esoarm_real)k * REF_TS;\n",
                               "#if !ESOARM_MOVE_TIME\n"
                               "    esoarm_real t = (esoarm_real)k * REF_TS;\n"
                               "#endif\n")
                + f"    esoarm_real previous = {_literal(ref.start)};\n"
                "    uint8_t i;\n"
                "    out[0] = previous; out[1] = R(0.0); out[2] = R(0.0);\n"
                "    for (i = 0; i < REF_NMOVES; ++i) {\n"
                "        esoarm_real t0 = REF_MOVES[3 * i], dur = REF_MOVES[3 * i + 1];\n"
                "        esoarm_real target = REF_MOVES[3 * i + 2];\n"
                "        esoarm_real delta = target - previous;\n"
                "#if ESOARM_MOVE_TIME\n"
                "        uint8_t after = (int32_t)k >= REF_KEND[i];\n"
                "        uint8_t during = !after && (int32_t)k >= REF_KSTART[i];\n"
                "        esoarm_real tau = R(0.0);\n"
                "        (void)t0; (void)dur;\n"
                "        if (during) tau = (esoarm_real)((int32_t)k - REF_KSTART[i]) * REF_TS"
                " + REF_OFFSET[i];\n"
                "#else  /* the Python reference's tests and t - t0, operation by operation */\n"
                "        esoarm_real tau = t - t0;\n"
                "        uint8_t after = t >= t0 + dur, during = !after && t >= t0;\n"
                "#endif\n"
                "        if (after) {\n"
                "            out[0] = target; out[1] = R(0.0); out[2] = R(0.0);\n"
                "        } else if (during) {\n"
                "#if ESOARM_RECIPROCAL  /* 1/dur, 1/dur^2 precomputed: no division */\n"
                "            esoarm_real s = tau * REF_INVERSE[2 * i], s2 = s * s;\n"
                "            out[0] = previous + delta * s2 * s * (R(10.0) - R(15.0) * s"
                " + R(6.0) * s2);\n"
                "            out[1] = delta * R(30.0) * s2 * (R(1.0) - R(2.0) * s + s2)"
                " * REF_INVERSE[2 * i];\n"
                "            out[2] = delta * R(60.0) * s * (R(1.0) - R(3.0) * s + R(2.0) * s2)"
                " * REF_INVERSE[2 * i + 1];\n"
                "#else\n"
                "            (void)REF_INVERSE;\n"
                "            esoarm_real s = tau / dur, s2 = s * s;\n"
                "            out[0] = previous + delta * s2 * s * (R(10.0) - R(15.0) * s"
                " + R(6.0) * s2);\n"
                "            out[1] = delta * R(30.0) * s2 * (R(1.0) - R(2.0) * s + s2) / dur;\n"
                "            out[2] = delta * R(60.0) * s * (R(1.0) - R(3.0) * s + R(2.0) * s2)"
                " / (dur * dur);\n"
                "#endif\n"
                "        }\n"
                "        previous = target;\n"
                "    }\n}\n")
    if isinstance(ref, Multisine):
        phases = ref.phases or [0.0] * len(ref.amplitudes)
        rows = [float(v) for trio in zip(ref.amplitudes, ref.frequencies, phases, strict=True)
                for v in trio]
        return (_array("REF_SINES", rows)
                + f"#define REF_NSINES {len(ref.amplitudes)}\n"
                + head
                + "    uint8_t i;\n"
                f"    out[0] = {_literal(ref.offset)}; out[1] = R(0.0); out[2] = R(0.0);\n"
                "    for (i = 0; i < REF_NSINES; ++i) {\n"
                "        esoarm_real a = REF_SINES[3 * i], w = REF_SINES[3 * i + 1];\n"
                "        esoarm_real arg = w * t + REF_SINES[3 * i + 2];\n"
                "        esoarm_real s = SIN(arg), c = COS(arg);\n"
                "        out[0] += a * s;\n"
                "        out[1] += a * w * c;\n"
                "        out[2] -= a * w * w * s;\n"
                "    }\n}\n")
    raise CodegenError(f"reference.kind = '{ref.kind}' has no C (quintic-steps or multisine)")


_MATH = {
    # name: (float32, float64)
    "FABS": ("fabsf", "fabs"), "POW": ("powf", "pow"), "COS": ("cosf", "cos"),
    "SIN": ("sinf", "sin"), "COPYSIGN": ("copysignf", "copysign"),
}


def _prelude(target: str, precision: str) -> str:
    single = precision == "float32"
    lines = ["#include <math.h>", "",
             "#define R(x) x##f" if single else "#define R(x) x"]
    for name, (f32, f64) in _MATH.items():
        lines.append(f"#define {name} {f32 if single else f64}")
    if target == "avr":  # avr-libc has lrint (half to even) but no rint
        lines.append("#define RINT(x) ((esoarm_real)lrint(x))")
    else:
        lines.append(f"#define RINT {'rintf' if single else 'rint'}")
    lines.append("#define ISFINITE(x) isfinite(x)")
    # float32: divisions by design constants become multiplications by their reciprocal,
    # which the compiler folds (a soft-float division costs ~500 AVR cycles); float64 keeps
    # the Python reference's divisions, operation by operation.
    lines.append("#define ESOARM_RECIPROCAL " + ("1" if single else "0"))
    # float32: the reference's time since each move's start from whole samples (see
    # _reference_c); float64 keeps the Python reference's t = k·Ts
    lines.append("#define ESOARM_MOVE_TIME " + ("1" if single else "0"))
    lines.append("#define DIV(a, b) ((a) * (R(1.0) / (b)))" if single
                 else "#define DIV(a, b) ((a) / (b))")
    return "\n".join(lines) + "\n"


def _state_size(text: str, macro: str, kind: str, names: dict[str, int]) -> int:
    """The value of ``#define MACRO expr`` in a kind's C: an integer expression of
    literals, ``+ - *``, parentheses and the generator's ``names`` (``OBS_N``)."""
    import ast

    def value(node: ast.AST) -> int:
        if isinstance(node, ast.Constant) and isinstance(node.value, int):
            return node.value
        if isinstance(node, ast.Name) and node.id in names:
            return names[node.id]
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add | ast.Sub | ast.Mult):
            a, b = value(node.left), value(node.right)
            return a + b if isinstance(node.op, ast.Add) else (
                a - b if isinstance(node.op, ast.Sub) else a * b)
        raise CodegenError(f"the C of kind '{kind}': {macro} is not an integer expression "
                           f"of {', '.join(names)}")  # pragma: no cover

    for line in text.splitlines():
        parts = line.split(None, 2)
        if len(parts) == 3 and parts[0] == "#define" and parts[1] == macro:
            return value(ast.parse(parts[2].split("/*")[0].strip(), mode="eval").body)
    raise CodegenError(f"the C of kind '{kind}' does not define {macro}")  # pragma: no cover


def generate(scn: Scenario, target: str = "host", precision: str = "float32",
             compensated: bool | None = None) -> Generated:
    """Generate the C of ``scn``'s observer, controller, reference and actuator.

    Parameters
    ----------
    scn : Scenario
        A one-joint scenario whose plant, observer and controller kinds have C.
    target : {"host", "avr", "cortex-m4"}
        The compiler's target (selects the math library spellings).
    precision : {"float32", "float64"}
        The type of every real in the generated code.
    compensated : bool, optional
        Sum the observer's increments with compensation; default: True for
        float32, False for float64 (float64 then repeats the Python step's
        arithmetic operation by operation).

    Returns
    -------
    Generated

    Raises
    ------
    CodegenError
        An unknown target or precision, a precision the target lacks, a kind
        without C, a reference kind without C, or more than one joint.

    Notes
    -----
    The steps: the options checked (:func:`_check_options`), the kinds' C
    (:func:`_kind_sources`), their designs, then the banner, the header and the source
    (:func:`_banner`, :func:`_header`, :func:`_reference_c`, ``_STEP``).
    """
    compensated = _check_options(target, precision, compensated)
    kinds = kinds_of(scn)
    texts = _kind_sources(kinds)
    plant = kinds.plant.design(scn)
    if plant.n_joints != 1:
        raise CodegenError(f"plant.kind = '{scn.plant.kind}' has {plant.n_joints} joints: "
                           "the generated controller runs one joint")
    ts = scn.sample_time
    obs = kinds.observer.design(scn, plant, ts)
    ctl = kinds.controller.design(scn, plant, ts)
    digest = scenario_hash(scn)
    sizes = {"OBS_N": obs.n_state, "CTL_N": ctl.n_state}
    nz = _state_size(texts["observer"], "OBS_NZ", kinds.observer.KIND, sizes)
    nc = _state_size(texts["controller"], "CTL_NC", kinds.controller.KIND, sizes)
    banner = _banner(scn, kinds, target, precision, compensated, digest)
    header = _header(scn, banner, digest, "float" if precision == "float32" else "double",
                     nz, nc)
    parts = [banner, f'#include "{HEADER}"\n', _prelude(target, precision),
             f"#define ESOARM_COMPENSATED {1 if compensated else 0}\n",
             f"#define REF_TS {_literal(ts)}\n",
             _array("OBS_P", obs.vector[1:]), _array("CTL_P", ctl.vector[1:]),
             _array("ACT_P", actuator_vector(scn)),
             f"#define OBS_N {obs.n_state}\n#define CTL_N {ctl.n_state}\n",
             f"\n/* ---- plant kind '{kinds.plant.KIND}' ---- */\n", texts["plant"],
             f"\n/* ---- observer kind '{kinds.observer.KIND}' ---- */\n", texts["observer"],
             f"\n/* ---- controller kind '{kinds.controller.KIND}' ---- */\n",
             texts["controller"], "\n/* ---- reference ---- */\n", _reference_c(scn),
             "\n/* ---- actuator ---- */\n",
             (resources.files("esoarm.codegen") / "actuator.c").read_text(encoding="utf-8"),
             "\n/* ---- the step ---- */\n", _STEP]
    return Generated(header, "".join(parts), scn.name, digest, target, precision, compensated)


def _check_options(target: str, precision: str, compensated: bool | None) -> bool:
    """The target and precision checked (CodegenError), and the compensation to use."""
    if target not in TARGETS:
        raise CodegenError(f"--target '{target}': one of {', '.join(TARGETS)}")
    if precision not in PRECISIONS:
        raise CodegenError(f"--precision '{precision}': one of {', '.join(PRECISIONS)}")
    if precision not in TARGETS[target]:
        raise CodegenError(f"--precision {precision} is not available on {target} "
                           f"(avr-gcc's double is 32 bits): use {TARGETS[target][0]}")
    if compensated is None:
        return precision == "float32"
    return compensated


def _kind_sources(kinds: Kinds) -> dict[str, str]:
    """The C of the plant, observer and controller kinds (CodegenError for a kind without)."""
    texts = {}
    for component, module in (("plant", kinds.plant), ("observer", kinds.observer),
                              ("controller", kinds.controller)):
        text = c_source(module)
        if text is None:
            raise CodegenError(f"{component}.kind = '{module.KIND}' has no C (C_SOURCE): "
                               "esoarm codegen cannot generate it")
        texts[component] = text
    return texts


def _banner(scn: Scenario, kinds: Kinds, target: str, precision: str, compensated: bool,
            digest: str) -> str:
    """The comment heading both files: how to regenerate them, from what, with what."""
    disc = getattr(scn.observer, "discretization", None)
    summary = (f" * observer: {kinds.observer.KIND}" + (f" ({disc})" if disc else "")
               + f", controller: {kinds.controller.KIND}, plant: {kinds.plant.KIND}"
               + (", motor (torque -> duty)" if scn.motor is not None else "") + "\n"
               + f" * Ts = {scn.sample_time!r} s ({scn.sensor.rate_hz:g} Hz), "
               f"{scn.n_samples} samples, torque limit {scn.actuator.torque_limit!r} N m\n")
    return (f"/* esoarm generated controller -- do not edit; regenerate with\n"
            f" *   esoarm codegen {scn.name} --target {target} --precision {precision}\n"
            f" * scenario: {scn.name}   sha256: {digest}\n"
            f" * target: {target}   precision: {precision}   observer sums: "
            f"{'compensated' if compensated else 'plain'}\n"
            + summary
            + f" * esoarm {__version__}\n */\n")


def _header(scn: Scenario, banner: str, digest: str, real: str, nz: int, nc: int) -> str:
    """``esoarm_controller.h``: the real type, the run's constants, the state, the two calls."""
    return (banner
            + "#ifndef ESOARM_CONTROLLER_H\n#define ESOARM_CONTROLLER_H\n\n"
            "#include <stdint.h>\n\n"
            f"typedef {real} esoarm_real;\n\n"
            f'#define ESOARM_SCENARIO "{scn.name}"\n'
            f'#define ESOARM_SCENARIO_HASH "{digest}"\n'
            f"#define ESOARM_SAMPLE_RATE_HZ {scn.sensor.rate_hz!r}\n"
            f"#define ESOARM_N_SAMPLES {scn.n_samples}UL\n"
            f"#define ESOARM_OBS_NZ {nz}\n#define ESOARM_CTL_NC {nc}\n\n"
            "/* Everything of one run: the observer state z (and its carried errors),\n"
            " * the estimate zhat, the controller state c, the sample index k, and the\n"
            " * outputs of the latest step. */\n"
            "typedef struct esoarm_state {\n"
            "    esoarm_real z[ESOARM_OBS_NZ];\n"
            "    esoarm_real zhat[3];\n"
            "    esoarm_real c[ESOARM_CTL_NC];\n"
            "    uint32_t k;\n"
            "    uint8_t started;\n"
            "    esoarm_real u;        /* saturated command [N m] */\n"
            "    esoarm_real applied;  /* torque the observer is updated with [N m] */\n"
            "    esoarm_real drive;    /* torque driving the plant [N m] */\n"
            "    esoarm_real duty;     /* PWM duty [counts], 0 without a motor */\n"
            "} esoarm_state;\n\n"
            "#ifdef __cplusplus\nextern \"C\" {\n#endif\n\n"
            "/* Before the first sample. */\n"
            "void esoarm_init(esoarm_state *s);\n"
            "/* One sample: the measured angle y_k [rad] -> the saturated command u_k [N m]. */\n"
            "esoarm_real esoarm_step(esoarm_state *s, esoarm_real y);\n\n"
            "#ifdef __cplusplus\n}\n#endif\n\n"
            "#endif\n")


_STEP = """void esoarm_init(esoarm_state *s)
{
    uint8_t i;
    for (i = 0; i < ESOARM_OBS_NZ; ++i) s->z[i] = R(0.0);
    for (i = 0; i < 3; ++i) s->zhat[i] = R(0.0);
    for (i = 0; i < ESOARM_CTL_NC; ++i) s->c[i] = R(0.0);
    s->k = 0;
    s->started = 0;
    s->u = s->applied = s->drive = s->duty = R(0.0);
}

esoarm_real esoarm_step(esoarm_state *s, esoarm_real y)
{
    esoarm_real ref[3];
    esoarm_real raw;
    if (!s->started) {
        obs_initialize(s->z, y);
        ctl_initialize(s->c, y);
        s->started = 1;
    }
    obs_estimate(s->z, y, s->zhat);
    ref_eval(s->k, ref);
    raw = ctl_control(s->c, s->zhat, y, ref, s->k);
    s->u = act_saturate(raw, ACT_P[0]);
    act_actuate(s->u, s->zhat[1], &s->applied, &s->drive, &s->duty);
    obs_advance(s->z, s->zhat, y, plant_observer_input(s->zhat, s->applied));
    s->k++;
    return s->u;
}
"""


def write_sources(gen: Generated, out: Path) -> list[Path]:
    """Write ``esoarm_controller.h`` and ``.c`` into the folder ``out`` (created).

    Parameters
    ----------
    gen : Generated
        From :func:`generate`.
    out : Path
        Destination folder.

    Returns
    -------
    list of Path
        The two files written.
    """
    from esoarm._io import atomic_path

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, text in ((HEADER, gen.header), (SOURCE, gen.source)):
        path = out / name
        with atomic_path(path) as tmp:
            Path(tmp).write_text(text, encoding="utf-8")
        paths.append(path)
    return paths
