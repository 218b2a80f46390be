"""C99 source for a scenario's observer and controller as designed, one generator for every kind.

The generated library is the sampled-data loop's steps 2, 3 and 5
(:mod:`esoarm.engines.loop`) for one joint, as
:class:`esoarm.hardware.host_control.DeploymentController` steps them, with the
reference supplied by the caller:

    first sample: initialize observer and controller from y_0
    ẑ_k = estimate(z_k, y_k)                        (observer kind's C)
    u_k = sat(control(ẑ_k, y_k, r_k))                (controller kind's C, ±torque_limit)
    u_k, drive_k, duty_k = actuate(u_k, ẑ2_k)        (motor: torque -> duty)
    z_{k+1} = advance(z_k, ẑ_k, y_k, v_k)            (v_k: the plant kind's observer input)

with r_k = (θd, θ̇d, θ̈d) an argument of the step.  The scenario's own moves are a
second, separate pair of files (``PREFIX_reference.h/.c``): a trajectory
generator the example sketch, the rig firmware and the PIL shells use; a
machine takes its setpoints from wherever it gets them.

Each kind provides its C once, beside its Python step: the module attribute
``C_SOURCE`` names a ``.c`` file in the kind's package (``observers/linear.c``
beside ``observers/linear.py``).  What a kind's C gets and gives:

- ``OBS_P`` / ``CTL_P``: the kind's design vector (without its CODE) as designed,
  ``static const``, with the Python step's indices; the entries that depend on
  the run-time parameters (ε, b0, k1, k2) are read from ``T``, the instance's
  copy of the vector (same indices), passed as the first argument of
  ``obs_estimate(T, z, y, zhat)``, ``obs_advance(T, z, zhat, y, u)`` and
  ``ctl_control(T, c, zhat, y, ref, first)``; structural entries (the
  discretization, Ts, Φ) stay in ``OBS_P`` so the compiler folds them;
- ``OBS_NZ`` / ``CTL_NC``: the size of its C state, an integer or an expression
  of ``OBS_N`` / ``CTL_N`` (the Python state's length for the design at hand);
- optionally ``obs_retune(T, eps, b0)`` / ``ctl_retune(T, k1, k2, b0)``
  returning 0, or -1 to refuse: the tunable entries of ``T`` recomputed from the
  parameters (the linear ESO's discrete gains: :c:func:`eso_linear_gain`); a
  kind without it refuses any change of its parameters;
- optionally ``OBS_NEXTRA`` / ``CTL_NEXTRA`` slots after the vector in ``T`` and
  ``obs_derive(T)`` / ``ctl_derive(T)`` filling them (reciprocals: a float32
  soft-float division costs ~500 AVR cycles).

A kind without ``C_SOURCE`` is refused (:class:`CodegenError`).  No heap, no
recursion, no globals but the ``static const`` design: everything of a run is in
the caller's ``PREFIX_state``; two instances (two axes) and two designs (two
prefixes) live in one program.

Precision: ``float64`` is the Python reference's arithmetic (on the host the
same operations in the same order); ``float32`` evaluates the same expressions
in single precision (on the AVR as ``double``, which avr-gcc makes 32 bits: no
promotion, avr-libc's ``cosf`` being ``cos``).  ``compensated`` (float32
default) sums the observer's increments with their rounding error carried to
the next sample (Kahan), which keeps the increments Ts·(…) that fall below half
an ulp of z (small ε, high rates) from being lost (see docs/on-the-chip.md).
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np

from esoarm import __version__
from esoarm.contract import Kind
from esoarm.kinds import Kinds, hook, kinds_of
from esoarm.plants import actuator
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
    "cortex-m0plus": ("float32", "float64"),
    "cortex-m4": ("float32", "float64"),
    "cortex-m7": ("float32", "float64"),
}
PRECISIONS = ("float32", "float64")
DEFAULT_PREFIX = "esoarm"

HEADER = "esoarm_controller.h"
SOURCE = "esoarm_controller.c"
REF_HEADER = "esoarm_reference.h"
REF_SOURCE = "esoarm_reference.c"


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
        ``PREFIX_controller.h`` and ``PREFIX_controller.c``: the library.
    ref_header, ref_source : str
        ``PREFIX_reference.h`` and ``.c``: the scenario's moves as a trajectory
        generator (for the example, the rig firmware and the PIL shells).
    scenario : str
        Scenario name.
    digest : str
        :func:`scenario_hash` of the scenario.
    target, precision : str
        As requested.
    compensated : bool
        The observer sums its increments with compensation.
    prefix : str
        Of every public name (``esoarm``: ``esoarm_step``, ``esoarm_state``).
    """

    header: str
    source: str
    scenario: str
    digest: str
    target: str
    precision: str
    compensated: bool
    prefix: str = DEFAULT_PREFIX
    ref_header: str = ""
    ref_source: str = ""

    @property
    def files(self) -> dict[str, str]:
        """File name -> text of the four generated files."""
        p = self.prefix
        return {f"{p}_controller.h": self.header, f"{p}_controller.c": self.source,
                f"{p}_reference.h": self.ref_header, f"{p}_reference.c": self.ref_source}


def _literal(x: float) -> str:
    """A C literal that parses to the double ``x`` exactly (wrapped in R(): the precision)."""
    if not np.isfinite(x):
        raise CodegenError(f"a design value is not finite ({x!r}): nothing to generate")
    text = repr(float(x))
    if "e" not in text and "." not in text:
        text += ".0"
    return f"R({text})"


#: The learned table's lookup takes |N θ̂ / 2π| below this as a number (a diverged estimate, or
#: NaN, gives no feedforward): the node below it, offset by a multiple of N, is then a uint16_t.
FF_RANGE = 30000


def _actuator_defines(act: np.ndarray) -> str:
    """The actuator's constants for the step and actuator.c, folded here in float64.

    ACT_SEES (the observer fed the command before saturation); with a ``[motor]`` table the
    torque → duty map's ACT_DUTY_GAIN = P(1 − δ)/K [counts/(N·m)], ACT_DUTY_TOP = P(1 − δ)
    and ACT_DUTY_DB = Pδ [counts], and the duty → torque map's ACT_TORQUE_GAIN = K/(P(1 − δ))
    [N·m/count] and ACT_TORQUE_DB = Kδ/(1 − δ) [N·m] (K stall gain, P pwm_max, δ deadband:
    :func:`esoarm.plants.motor.torque_to_duty` and :func:`~esoarm.plants.motor.source_torque`
    as one product and one sum each) and ACT_DUTY_DEAD = ⌊Pδ⌋, the duties that give no
    torque; ACT_FF_N, the learned table's bins N (0 without one),
    and with one ACT_FF_SCALE = N/2π [1/rad], ACT_FF_OFFSET, the multiple of N at or above
    :data:`FF_RANGE` that makes the node below any angle in range non-negative, and
    ACT_FF_TOP = N·2^k, the largest of these under 2^16 (the wrap into [0, N) subtracts
    N·2^k, k from there down to 0).
    """
    sees = 1 if act[actuator.SEES] == actuator.SEES_COMMANDED else 0
    lines = [f"#define ACT_SEES {sees}"]
    stall, _, pwm, db = (float(v) for v in act[actuator.MOTOR_BLOCK:actuator.PWM_LEVELS])
    folded = dict.fromkeys(("DUTY_GAIN", "DUTY_TOP", "DUTY_DB", "TORQUE_GAIN", "TORQUE_DB"),
                           "R(0.0)")  # read only with a motor
    if act[actuator.MOTOR] != 0.0:
        top = pwm * (1.0 - db)
        folded.update(DUTY_GAIN=_literal(top / stall), DUTY_TOP=_literal(top),
                      DUTY_DB=_literal(pwm * db), TORQUE_GAIN=_literal(stall / top),
                      TORQUE_DB=_literal(stall * db / (1.0 - db)))
    lines += [f"#define ACT_{name} {value}" for name, value in folded.items()]
    dead = math.floor(pwm * db) if act[actuator.MOTOR] != 0.0 else 0
    lines.append(f"#define ACT_DUTY_DEAD {dead}L")
    bins = actuator.table_bins(act)
    lines.append(f"#define ACT_FF_N {bins}")
    if bins:
        lines += [f"#define ACT_FF_SCALE {_literal(bins / (2.0 * np.pi))}",
                  f"#define ACT_FF_OFFSET {bins * -(-FF_RANGE // bins)}u",
                  f"#define ACT_FF_TOP {bins << ((0xFFFF // bins).bit_length() - 1)}u"]
    return "\n".join(lines) + "\n"


def _actuator_arrays(act: np.ndarray) -> str:
    """ACT_P (the actuator vector up to the learned table's bin count), the table ACT_FF and
    its slopes ACT_FF_D.

    The table's node i is −I0·m_i [N·m] and its slope m_{i+1} − m_i (wrapping at N; in
    float64 here), so that the lookup interpolates with one product.  On the AVR both are in
    flash (``PROGMEM``, read with ``pgm_read_float``: avr-gcc's double is 32 bits), not
    copied into the 2 KiB of RAM at start-up; elsewhere const arrays (flash on the Cortex-M
    parts).  ``ACT_FF_AT(i)`` and ``ACT_FF_D_AT(i)`` read node i and its slope.
    """
    bins = actuator.table_bins(act)
    if bins == 0:
        return _array("ACT_P", act)
    table = np.asarray(act[actuator.FF_BINS + 1:actuator.FF_BINS + 1 + bins], dtype=float)
    slope = np.roll(table, -1) - table
    items = ", ".join(_literal(float(v)) for v in table)
    slopes = ", ".join(_literal(float(v)) for v in slope)
    return (_array("ACT_P", act[:actuator.FF_BINS + 1])
            + "/* the learned feedforward table -I0 m_i [N m] (controller.feedforward_map) and\n"
            " * its slopes -I0 (m_{i+1} - m_i) [N m per bin] */\n"
            "#if defined(__AVR__)\n#include <avr/pgmspace.h>\n"
            "typedef char act_ff_is_32_bits[sizeof(esoarm_real) == 4 ? 1 : -1];\n"
            f"static const esoarm_real ACT_FF[{bins}] PROGMEM = {{{items}}};\n"
            f"static const esoarm_real ACT_FF_D[{bins}] PROGMEM = {{{slopes}}};\n"
            "#define ACT_FF_AT(i) ((esoarm_real)pgm_read_float(&ACT_FF[(i)]))\n"
            "#define ACT_FF_D_AT(i) ((esoarm_real)pgm_read_float(&ACT_FF_D[(i)]))\n#else\n"
            f"static const esoarm_real ACT_FF[{bins}] = {{{items}}};\n"
            f"static const esoarm_real ACT_FF_D[{bins}] = {{{slopes}}};\n"
            "#define ACT_FF_AT(i) (ACT_FF[(i)])\n#define ACT_FF_D_AT(i) (ACT_FF_D[(i)])\n"
            "#endif\n")


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


def _reference_c(scn: Scenario) -> tuple[str, str]:
    """(struct members, functions) of the scenario's reference as an on-chip generator.

    Quintic steps: whole samples decide before/in/after each move with the Python
    reference's own tests on t_k = k·Ts (float64, at generation), the fraction of a move
    is s = (k − K_start)·Ts/T + F/T with F = K_start·Ts − t0, which keeps float32's relative
    precision within the move, and its three polynomials carry the move's Δ, 1/T and 1/T²
    folded in at generation (Horner's rule: 21 operations a sample inside a move where the
    formula written out took 30; on the ATmega328P about 0.5k cycles less a sample); k stops
    counting after the last move (the target is held for ever: no counter runs out).
    Multisine: each sine's phase is carried modulo 2π.
    """
    ref = scn.reference
    ts = scn.sample_time
    if isinstance(ref, QuinticSteps):
        targets = [float(target) for _, _, target in ref.moves]
        starts = [_first_sample(ts, t0) for t0, _, _ in ref.moves]
        ends = [_first_sample(ts, t0 + dur) for t0, dur, _ in ref.moves]
        # s = (k − K_start)·(Ts/T) + (K_start·Ts − t0)/T: the move's fraction, one product
        # and one sum; its three polynomials in s with the move's Δ, 1/T and 1/T² folded in
        scale, poly = [], []
        previous = float(ref.start)
        for (t0, dur, target), k in zip(ref.moves, starts, strict=True):
            delta = float(target) - previous
            scale += [ts / dur, (k * ts - t0) / dur]
            poly += [6.0 * delta, -15.0 * delta, 10.0 * delta,
                     30.0 * delta / dur, -60.0 * delta / dur, 30.0 * delta / dur,
                     120.0 * delta / dur**2, -180.0 * delta / dur**2, 60.0 * delta / dur**2]
            previous = float(target)
        n = len(ref.moves)
        members = "    uint32_t k;  /* sample index, stops after the last move */\n"
        body = (_array("REF_TARGET", targets or [0.0]) + _array("REF_SCALE", scale or [0.0])
                + _array("REF_POLY", poly or [0.0])
                + f"static const uint32_t REF_KSTART[{max(n, 1)}] = "
                + "{" + (", ".join(f"{k}UL" for k in starts) or "0UL") + "};\n"
                + f"static const uint32_t REF_KEND[{max(n, 1)}] = "
                + "{" + (", ".join(f"{k}UL" for k in ends) or "0UL") + "};\n"
                + f"#define REF_NMOVES {n}u\n#define REF_KLAST {max(ends, default=0)}UL\n\n"
                "void @P@_reference_init(@P@_reference *r)\n{\n    r->k = 0;\n}\n\n"
                "/* Move i from the previous target by delta over T: with s = (t - t0)/T,\n"
                " * theta = previous + delta s^3 (10 - 15 s + 6 s^2),\n"
                " * omega = 30 delta s^2 (1 - 2 s + s^2) / T,\n"
                " * alpha = 60 delta s (1 - 3 s + 2 s^2) / T^2\n"
                " * (esoarm.reference), each polynomial by Horner's rule with delta and T\n"
                " * folded into REF_POLY at generation: 21 operations a sample in a move. */\n"
                "void @P@_reference_next(@P@_reference *r, esoarm_real out[3])\n{\n"
                f"    esoarm_real previous = {_literal(ref.start)};\n"
                "    uint32_t k = r->k;\n"
                "    unsigned i;\n"
                "    out[0] = previous; out[1] = R(0.0); out[2] = R(0.0);\n"
                "    for (i = 0; i < REF_NMOVES; ++i) {\n"
                "        if (k >= REF_KEND[i]) {\n"
                "            out[0] = REF_TARGET[i]; out[1] = R(0.0); out[2] = R(0.0);\n"
                "        } else if (k >= REF_KSTART[i]) {\n"
                "            const esoarm_real *c = &REF_POLY[9 * i];\n"
                "            esoarm_real s = (esoarm_real)(k - REF_KSTART[i]) * REF_SCALE[2 * i]"
                " + REF_SCALE[2 * i + 1];\n"
                "            esoarm_real s2 = s * s;\n"
                "            out[0] = previous + s2 * s * ((c[0] * s + c[1]) * s + c[2]);\n"
                "            out[1] = s2 * ((c[3] * s + c[4]) * s + c[5]);\n"
                "            out[2] = s * ((c[6] * s + c[7]) * s + c[8]);\n"
                "        }\n"
                "        previous = REF_TARGET[i];\n"
                "    }\n"
                "    if (k < REF_KLAST) r->k = k + 1u;\n"
                "}\n")
        return members, body
    if isinstance(ref, Multisine):
        phases = ref.phases or [0.0] * len(ref.amplitudes)
        n = len(ref.amplitudes)
        steps = [w * ts for w in ref.frequencies]
        members = f"    esoarm_real phase[{max(n, 1)}];  /* of each sine, in [0, 2 pi) [rad] */\n"
        body = (_array("REF_AMP", ref.amplitudes or [0.0])
                + _array("REF_W", ref.frequencies or [0.0])
                + _array("REF_PHASE0", [math.fmod(p, 2 * math.pi) % (2 * math.pi)
                                        for p in phases] or [0.0])
                + _array("REF_DPHASE", [math.fmod(s, 2 * math.pi) for s in steps] or [0.0])
                + f"#define REF_NSINES {n}u\n#define REF_TWO_PI {_literal(2 * math.pi)}\n\n"
                "void @P@_reference_init(@P@_reference *r)\n{\n    unsigned i;\n"
                "    for (i = 0; i < REF_NSINES; ++i) r->phase[i] = REF_PHASE0[i];\n}\n\n"
                "void @P@_reference_next(@P@_reference *r, esoarm_real out[3])\n{\n"
                "    unsigned i;\n"
                f"    out[0] = {_literal(ref.offset)}; out[1] = R(0.0); out[2] = R(0.0);\n"
                "    for (i = 0; i < REF_NSINES; ++i) {\n"
                "        esoarm_real a = REF_AMP[i], w = REF_W[i], arg = r->phase[i];\n"
                "        esoarm_real s = SIN(arg), c = COS(arg);\n"
                "        out[0] += a * s;\n"
                "        out[1] += a * w * c;\n"
                "        out[2] -= a * w * w * s;\n"
                "        arg += REF_DPHASE[i];\n"
                "        if (arg >= REF_TWO_PI) arg -= REF_TWO_PI;\n"
                "        r->phase[i] = arg;\n"
                "    }\n}\n")
        return members, body
    raise CodegenError(f"reference.kind = '{ref.kind}': the generated reference has "
                       "quintic-steps or multisine only")


_MATH = {
    # name: (float32, float64)
    "FABS": ("fabsf", "fabs"), "POW": ("powf", "pow"), "COS": ("cosf", "cos"),
    "SIN": ("sinf", "sin"), "COPYSIGN": ("copysignf", "copysign"), "EXP": ("expf", "exp"),
    "FLOOR": ("floorf", "floor"), "TANH": ("tanhf", "tanh"), "LRINT": ("lrintf", "lrint"),
}


def _prelude(target: str, precision: str) -> str:
    # avr: the real is double, which avr-gcc makes 32 bits (checked at compile time), so
    # avr-libc's double functions take it without a promotion (its cosf is a macro for cos)
    single = precision == "float32" and target != "avr"
    lines = ["#include <math.h>", "",
             "#define R(x) x##f" if single else "#define R(x) x"]
    for name, (f32, f64) in _MATH.items():
        lines.append(f"#define {name} {f32 if single else f64}")
    if target == "avr":  # avr-libc has lrint (half to even) but no rint
        lines += ["#if defined(__SIZEOF_DOUBLE__) && __SIZEOF_DOUBLE__ != 4",
                  '#error "generated for avr-gcc\'s 32-bit double: build without -mdouble=64"',
                  "#endif",
                  "#define RINT(x) ((esoarm_real)lrint(x))"]
    else:
        lines.append(f"#define RINT {'rintf' if single else 'rint'}")
    lines.append("#define ISFINITE(x) isfinite(x)")
    # float32: divisions by design constants become multiplications by their reciprocal,
    # which the compiler folds (a soft-float division costs ~500 AVR cycles); float64 keeps
    # the Python reference's divisions, operation by operation.
    lines.append("#define ESOARM_RECIPROCAL " + ("1" if precision == "float32" else "0"))
    lines.append("#define DIV(a, b) ((a) * (R(1.0) / (b)))" if precision == "float32"
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
    if macro.endswith("NEXTRA"):
        return 0
    raise CodegenError(f"the C of kind '{kind}' does not define {macro}")  # pragma: no cover


#: The linear ESO's discrete gains in C, for kinds that retune at run time.
_ESO_GAIN = """
/* The linear ESO's gains for epsilon [s] at Ts [s] (esoarm.observers.linear.design_observer):
 * beta = (3/eps, 3/eps^2, 1/eps^3); the discrete gain for disc 0 "euler" (Ts beta), 1 "zoh"
 * (Lp, the triple pole p = exp(-Ts/eps) of Phi - Lp C in closed form: with a = 1 - p,
 * Lp = (3a, (3a^2 - a^3/2)/Ts, a^3/Ts^2)) or 2 "current" (Lc = Phi^-1 Lp); beta and the gain
 * times scale (0.5: the half-gain tuning).  0, or -1 when eps is not a positive finite
 * number. */
static int eso_linear_gain(esoarm_real disc, esoarm_real ts, esoarm_real eps,
                           esoarm_real scale, esoarm_real beta[3], esoarm_real gain[3])
{
    esoarm_real x, a, l1, l2, l3;
    if (!(eps > R(0.0)) || !ISFINITE(eps)) return -1;
    beta[0] = scale * (R(3.0) / eps);
    beta[1] = scale * (R(3.0) / (eps * eps));
    beta[2] = scale * (R(1.0) / (eps * eps * eps));
    if (disc == R(0.0)) {
        gain[0] = ts * beta[0]; gain[1] = ts * beta[1]; gain[2] = ts * beta[2];
        return 0;
    }
    x = ts / eps;
    /* a = 1 - exp(-x); its series below x = 0.01 keeps a's relative precision */
    if (x < R(0.01)) a = x * (R(1.0) - x * R(0.5) * (R(1.0) - x * (R(1.0) / R(3.0))
                                                     * (R(1.0) - x * R(0.25))));
    else a = R(1.0) - EXP(-x);
    l1 = R(3.0) * a;
    l2 = (R(3.0) * a * a - R(0.5) * a * a * a) / ts;
    l3 = a * a * a / (ts * ts);
    if (disc == R(1.0)) {
        gain[0] = scale * l1; gain[1] = scale * l2; gain[2] = scale * l3;
    } else {    /* Phi^-1 = [[1, -Ts, Ts^2/2], [0, 1, -Ts], [0, 0, 1]] */
        gain[0] = scale * (l1 - ts * l2 + R(0.5) * ts * ts * l3);
        gain[1] = scale * (l2 - ts * l3);
        gain[2] = scale * l3;
    }
    return 0;
}
"""

_PREFIX = re.compile(r"[a-z][a-z0-9_]{0,23}")


def check_prefix(prefix: str) -> str:
    """``prefix`` if it is a lower-case C identifier of at most 24 characters.

    Parameters
    ----------
    prefix : str
        The prefix of the generated C names (``--prefix``).

    Returns
    -------
    str
        ``prefix`` itself.

    Raises
    ------
    CodegenError
        Not such an identifier (one line naming ``--prefix``).
    """
    if not _PREFIX.fullmatch(prefix):
        raise CodegenError(f"--prefix '{prefix}': a lower-case C identifier (a-z, 0-9, _; "
                           "starting with a letter, at most 24 characters)")
    return prefix


def _tunable(scn: Scenario, kinds: object) -> tuple[float, float, float, float]:
    """ε, b0, k1, k2 of the design (k1, k2: 0 for a controller without them)."""
    plant = kinds.plant.design(scn)  # type: ignore[attr-defined]
    b0 = float(np.asarray(plant.b0, dtype=float).ravel()[0])
    eps = getattr(scn.observer, "eps", 0.0)
    eps = float(eps[0] if isinstance(eps, list) else eps)
    k1 = float(getattr(scn.controller, "k1", 0.0) or 0.0)
    k2 = float(getattr(scn.controller, "k2", 0.0) or 0.0)
    return eps, b0, k1, k2


def generate(scn: Scenario, target: str = "host", precision: str = "float32",
             compensated: bool | None = None, prefix: str = DEFAULT_PREFIX) -> Generated:
    """Generate the C of ``scn``'s observer, controller and actuator, and its reference.

    Parameters
    ----------
    scn : Scenario
        A one-joint scenario whose plant, observer and controller kinds have C.
    target : {"host", "avr", "cortex-m0plus", "cortex-m4", "cortex-m7"}
        The compiler's target (selects the math library spellings and the real type).
    precision : {"float32", "float64"}
        The type of every real in the generated code.
    compensated : bool, optional
        Sum the observer's increments with compensation; default: True for
        float32, False for float64 (float64 then repeats the Python step's
        arithmetic operation by operation).
    prefix : str
        Of every public name and file: two designs link into one program with
        two prefixes.

    Returns
    -------
    Generated

    Raises
    ------
    CodegenError
        An unknown target, precision or prefix, a precision the target lacks, a
        kind without C, a reference kind without C, or more than one joint.

    Notes
    -----
    The steps: the options checked (:func:`_check_options`), the kinds' C
    (:func:`_kind_sources`), their designs, the banner (:func:`_banner`), the header,
    the source with the hooks of kinds without run-time tuning
    (:func:`_fixed_gain_hooks`, :func:`_observer_defines`), and the reference's files
    (:func:`_reference_files`).
    """
    compensated = _check_options(target, precision, compensated, prefix)
    kinds = kinds_of(scn)
    texts = _kind_sources(kinds)
    plant = kinds.plant.design(scn)
    if plant.n_joints != 1:
        raise CodegenError(f"plant.kind = '{scn.plant.kind}' has {plant.n_joints} joints: "
                           "the generated controller runs one joint (codegen, pil and the "
                           "on-board modes serve one-joint scenarios such as test-1)")
    ts = scn.sample_time
    obs = kinds.observer.design(scn, plant, ts)
    ctl = kinds.controller.design(scn, plant, ts)
    act = actuator_vector(scn)
    digest = scenario_hash(scn)
    sizes = {"OBS_N": obs.n_state, "CTL_N": ctl.n_state}
    nz = _state_size(texts["observer"], "OBS_NZ", kinds.observer.KIND, sizes)
    nc = _state_size(texts["controller"], "CTL_NC", kinds.controller.KIND, sizes)
    ox = _state_size(texts["observer"], "OBS_NEXTRA", kinds.observer.KIND, sizes)
    cx = _state_size(texts["controller"], "CTL_NEXTRA", kinds.controller.KIND, sizes)
    onp, cnp = len(obs.vector) - 1, len(ctl.vector) - 1
    eps, b0, k1, k2 = _tunable(scn, kinds)
    p, up = prefix, prefix.upper()
    real = ("double" if target == "avr" or precision == "float64" else "float")
    banner = _banner(scn, kinds, target, precision, compensated, prefix, digest)
    sub = {"@P@": p, "@U@": up}

    def fill(text: str) -> str:
        for key, val in sub.items():
            text = text.replace(key, val)
        return text

    header = fill(banner + _HEADER.format(
        real=real, real_note=("avr-gcc's double is 32 bits: float32" if target == "avr"
                              and real == "double" else precision),
        scenario=scn.name, digest=digest, version=__version__, rate=repr(scn.sensor.rate_hz),
        ts=repr(ts), comp=1 if compensated else 0, nz=nz, nc=nc, onp=onp + ox, cnp=cnp + cx,
        limit=repr(scn.actuator.torque_limit),
        eps=repr(eps), b0=repr(b0), k1=repr(k1), k2=repr(k2),
        k_note=("flc: alpha = accel_d - k1 (zhat2 - omega_d) - k2 (zhat1 - theta_d)"
                if hook(kinds.controller, "FLC_LAW") else
                f"not used by controller '{kinds.controller.KIND}': a change is refused")))
    local_real = ("" if p == "esoarm" else "#ifndef ESOARM_LOCAL_REAL\n#define ESOARM_LOCAL_REAL\n"
                  f"typedef {p}_real esoarm_real;\n#endif\n")
    obs_text, ctl_text = texts["observer"], texts["controller"]
    defaults = _fixed_gain_hooks(obs_text, ctl_text)
    extra = _observer_defines(scn)
    parts = [banner, f'#include "{p}_controller.h"\n', local_real, _prelude(target, precision),
             f"#define ESOARM_COMPENSATED {1 if compensated else 0}\n",
             _array("OBS_P", obs.vector[1:]), _array("CTL_P", ctl.vector[1:]),
             _actuator_arrays(act),
             f"#define OBS_N {obs.n_state}\n#define CTL_N {ctl.n_state}\n"
             f"#define OBS_NP {onp}\n#define CTL_NP {cnp}\n", extra,
             _ESO_GAIN if "eso_linear_gain" in obs_text else "",
             f"\n/* ---- plant kind '{kinds.plant.KIND}' ---- */\n", texts["plant"],
             f"\n/* ---- observer kind '{kinds.observer.KIND}' ---- */\n", obs_text,
             f"\n/* ---- controller kind '{kinds.controller.KIND}' ---- */\n", ctl_text,
             "\n/* ---- kinds without run-time tuning ---- */\n" if defaults else "",
             *defaults,
             "\n/* ---- actuator ---- */\n", _actuator_defines(act),
             (resources.files("esoarm.codegen") / "actuator.c").read_text(encoding="utf-8"),
             "\n/* ---- the step ---- */\n",
             "".join(f"#define {up}_{name}0 {_literal(v)}\n" for name, v in
                     (("EPS", eps), ("B0", b0), ("K1", k1), ("K2", k2))),
             fill(_STEP)]
    ref_header, ref_source = (fill(text) for text in _reference_files(
        scn, banner, p, local_real, target, precision))
    return Generated(header, "".join(parts), scn.name, digest, target, precision, compensated,
                     prefix, ref_header, ref_source)


def _check_options(target: str, precision: str, compensated: bool | None, prefix: str) -> bool:
    """The target, precision and prefix checked (CodegenError), and the compensation to use."""
    if target not in TARGETS:
        raise CodegenError(f"--target '{target}': one of {', '.join(TARGETS)}")
    if precision not in PRECISIONS:
        raise CodegenError(f"--precision '{precision}': one of {', '.join(PRECISIONS)}")
    if precision not in TARGETS[target]:
        raise CodegenError(f"--precision {precision} is not available on {target} "
                           f"(avr-gcc's double is 32 bits): use {TARGETS[target][0]}")
    check_prefix(prefix)
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
            from esoarm.kinds import CONTROLLERS, OBSERVERS, PLANTS

            family = {"plant": PLANTS, "observer": OBSERVERS, "controller": CONTROLLERS}
            with_c = ", ".join(m.KIND for m in family[component] if c_source(m))
            raise CodegenError(f"{component}.kind = '{module.KIND}' has no C code: "
                               "codegen, pil and the on-board modes run the "
                               f"{component} kinds {with_c}")
        texts[component] = text
    return texts


def _banner(scn: Scenario, kinds: Kinds, target: str, precision: str, compensated: bool,
            prefix: str, digest: str) -> str:
    """The comment heading the files: how to regenerate them, from what, with what."""
    ts = scn.sample_time
    disc = getattr(scn.observer, "discretization", None)
    summary = (f" * observer: {kinds.observer.KIND}" + (f" ({disc})" if disc else "")
               + f", controller: {kinds.controller.KIND}, plant: {kinds.plant.KIND}"
               + (", motor (torque -> duty)" if scn.motor is not None else "") + "\n"
               + f" * Ts = {ts!r} s ({scn.sensor.rate_hz:g} Hz), "
               f"torque limit {scn.actuator.torque_limit!r} N m\n")
    command = (f"esoarm codegen {scn.name} --target {target} --precision {precision}"
               + ("" if compensated == (precision == "float32") else
                  (" --plain-sums" if not compensated else ""))
               + ("" if prefix == DEFAULT_PREFIX else f" --prefix {prefix}"))
    return (f"/* esoarm generated controller -- do not edit; regenerate with\n"
            f" *   {command}\n"
            f" * scenario: {scn.name}   sha256: {digest}   esoarm {__version__}\n"
            f" * target: {target}   precision: {precision}   observer sums: "
            f"{'compensated' if compensated else 'plain'}\n"
            + summary + " */\n")


def _fixed_gain_hooks(obs_text: str, ctl_text: str) -> list[str]:
    """The retune/derive hooks a kind's C lacks: its gains are fixed at generation."""
    defaults = []
    if "obs_retune" not in obs_text:
        defaults.append("static int obs_retune(esoarm_real T[], esoarm_real eps, "
                        "esoarm_real b0)\n{\n    (void)T; (void)eps; (void)b0;\n"
                        "    return -1;  /* this kind's gains are fixed at generation */\n}\n")
    if "obs_derive" not in obs_text:
        defaults.append("static void obs_derive(esoarm_real T[])\n{\n    (void)T;\n}\n")
    if "ctl_retune" not in ctl_text:
        defaults.append("static int ctl_retune(esoarm_real T[], esoarm_real k1, "
                        "esoarm_real k2, esoarm_real b0)\n{\n    (void)T; (void)k1; (void)k2;"
                        " (void)b0;\n    return -1;\n}\n")
    if "ctl_derive" not in ctl_text:
        defaults.append("static void ctl_derive(esoarm_real T[])\n{\n    (void)T;\n}\n")
    return defaults


def _observer_defines(scn: Scenario) -> str:
    """``OBS_RATIO`` (a cascade's), ``OBS_GAIN_SCALE`` (0.5 for the half-gain tuning) and
    ``OBS_MODEL_FORM`` (1 for the linear ESO's ``delay_form = "model"``)."""
    extra = ""
    ratio = getattr(scn.observer, "ratio", None)
    if ratio is not None:
        extra += f"#define OBS_RATIO {_literal(float(ratio))}\n"
    half = getattr(scn.observer, "tuning", "bandwidth") == "half-gain"
    extra += f"#define OBS_GAIN_SCALE {_literal(0.5 if half else 1.0)}\n"
    model = getattr(scn.observer, "delay_form", "input") == "model"
    extra += f"#define OBS_MODEL_FORM {1 if model else 0}\n"
    return extra


def _reference_files(scn: Scenario, banner: str, p: str, local_real: str, target: str,
                     precision: str) -> tuple[str, str]:
    """The reference's header and source, their prefix placeholders not yet filled."""
    members, ref_body = _reference_c(scn)
    ref_banner = banner.replace("generated controller", "generated reference (the scenario's "
                                "moves, for the example)")
    ref_header = ref_banner + _REF_HEADER.format(
        members=members, kind=scn.reference.kind, n=scn.n_samples)
    ref_source = "".join([
        ref_banner, f'#include "{p}_reference.h"\n', local_real, _prelude(target, precision),
        f"#define REF_TS {_literal(scn.sample_time)}\n", ref_body])
    return ref_header, ref_source


_HEADER = """#ifndef @U@_CONTROLLER_H
#define @U@_CONTROLLER_H

#include <stdint.h>

/* Every real of the controller ({real_note}). */
typedef {real} @P@_real;

#define @U@_SCENARIO "{scenario}"
#define @U@_SCENARIO_HASH "{digest}"
#define @U@_ESOARM_VERSION "{version}"
#define @U@_SAMPLE_RATE_HZ {rate}
#define @U@_SAMPLE_TIME_S {ts}
#define @U@_TORQUE_LIMIT {limit}
#define @U@_COMPENSATED {comp}
#define @U@_OBS_NZ {nz}
#define @U@_CTL_NC {nc}
#define @U@_OBS_NT {onp}
#define @U@_CTL_NT {cnp}

/* Fault bits of @P@_state.fault (sticky until @P@_reset or @P@_init). */
#define @U@_FAULT_MEASUREMENT 1u  /* a y that is not finite: refused, last command held */
#define @U@_FAULT_REFERENCE 2u    /* a reference that is not finite: refused, command held */
#define @U@_FAULT_PARAMS 4u       /* @P@_set_params refused the parameters (old ones kept) */
#define @U@_FAULT_STATE 8u        /* the step computed a command that is not finite: held */

/* The parameters that can change at run time (@P@_set_params): the design's values
 * after @P@_init. */
typedef struct @P@_params {{
    @P@_real eps;  /* observer epsilon [s] (> 0; design {eps}) */
    @P@_real b0;   /* input gain 1/I0 [1/(kg m^2)] (design {b0}) */
    @P@_real k1;   /* error-rate gain [1/s] (design {k1}; {k_note}) */
    @P@_real k2;   /* error gain [1/s^2] (design {k2}) */
}} @P@_params;

/* Everything of one controller instance (one per axis); read the outputs, write nothing. */
typedef struct @P@_state {{
    @P@_params par;                /* in use */
    @P@_real obs_t[@U@_OBS_NT];    /* the observer's gains for par (and derived values) */
    @P@_real ctl_t[@U@_CTL_NT];    /* the controller's */
    @P@_real z[@U@_OBS_NZ];        /* observer state (and its carried rounding errors) */
    @P@_real zhat[3];              /* estimate: angle [rad], rate [rad/s], total disturbance
                                    * [rad/s^2] */
    @P@_real c[@U@_CTL_NC];        /* controller state */
    @P@_real u;                    /* saturated command [N m] */
    @P@_real applied;              /* torque the observer is updated with [N m] */
    @P@_real drive;                /* torque driving the plant [N m] */
    @P@_real duty;                 /* PWM duty [counts, signed], 0 without a [motor] table */
    uint8_t started;               /* 0 until the first step */
    uint8_t fault;                 /* @U@_FAULT_* bits */
}} @P@_state;

#ifdef __cplusplus
extern "C" {{
#endif

/* Before the first sample: the design's parameters, the state cleared, no fault. */
void @P@_init(@P@_state *s);
/* Start again from the next measurement (observer and controller re-initialized from it),
 * faults cleared, the parameters in use kept. */
void @P@_reset(@P@_state *s);
/* The design's parameters. */
void @P@_default_params(@P@_params *par);
/* Use `par` from the next step: the observer's discrete gains and the controller's gains
 * recomputed.  0, or -1 (and @U@_FAULT_PARAMS) when refused: epsilon or b0 not positive and
 * finite, or a parameter this design's kinds cannot change; the old ones stay.  Call it
 * between steps (with the sample interrupt masked when the step runs in one). */
int @P@_set_params(@P@_state *s, const @P@_params *par);
/* One sample, every Ts = {ts} s: the measured angle y [rad] and the reference angle
 * theta_d [rad], rate omega_d [rad/s] and acceleration accel_d [rad/s^2] at this sample ->
 * the saturated command u [N m] (also s->u; s->duty the PWM duty).  A y or reference
 * that is not finite is refused: the last command is returned and a fault bit set. */
@P@_real @P@_step(@P@_state *s, @P@_real y, @P@_real theta_d, @P@_real omega_d,
                  @P@_real accel_d);

#ifdef __cplusplus
}}
#endif

#endif
"""

_REF_HEADER = """#ifndef @U@_REFERENCE_H
#define @U@_REFERENCE_H

#include "@P@_controller.h"

/* The scenario's reference ({kind}; {n} samples in the scenario's run) as an on-chip
 * trajectory generator: @P@_reference_next gives theta_d [rad], omega_d [rad/s] and
 * accel_d [rad/s^2] at the next sample (Ts = @U@_SAMPLE_TIME_S s), for ever (after the last
 * move the target is held; no counter runs out). */
typedef struct @P@_reference {{
{members}}} @P@_reference;

#ifdef __cplusplus
extern "C" {{
#endif

void @P@_reference_init(@P@_reference *r);
void @P@_reference_next(@P@_reference *r, @P@_real out[3]);

#ifdef __cplusplus
}}
#endif

#endif
"""

_STEP = """void @P@_default_params(@P@_params *par)
{
    par->eps = @U@_EPS0;
    par->b0 = @U@_B00;
    par->k1 = @U@_K10;
    par->k2 = @U@_K20;
}

void @P@_reset(@P@_state *s)
{
    unsigned i;
    for (i = 0; i < @U@_OBS_NZ; ++i) s->z[i] = R(0.0);
    for (i = 0; i < 3; ++i) s->zhat[i] = R(0.0);
    for (i = 0; i < @U@_CTL_NC; ++i) s->c[i] = R(0.0);
    s->started = 0;
    s->fault = 0;
    s->u = s->applied = s->drive = s->duty = R(0.0);
}

void @P@_init(@P@_state *s)
{
    unsigned i;
    for (i = 0; i < OBS_NP; ++i) s->obs_t[i] = OBS_P[i];
    for (i = 0; i < CTL_NP; ++i) s->ctl_t[i] = CTL_P[i];
    for (i = OBS_NP; i < @U@_OBS_NT; ++i) s->obs_t[i] = R(0.0);
    for (i = CTL_NP; i < @U@_CTL_NT; ++i) s->ctl_t[i] = R(0.0);
    obs_derive(s->obs_t);
    ctl_derive(s->ctl_t);
    @P@_default_params(&s->par);
    @P@_reset(s);
}

int @P@_set_params(@P@_state *s, const @P@_params *par)
{
    esoarm_real obs_t[@U@_OBS_NT], ctl_t[@U@_CTL_NT];
    unsigned i;
    int bad = !(par->eps > R(0.0)) || !ISFINITE(par->eps) || !(par->b0 != R(0.0))
              || !ISFINITE(par->b0) || !ISFINITE(par->k1) || !ISFINITE(par->k2);
    for (i = 0; i < @U@_OBS_NT; ++i) obs_t[i] = s->obs_t[i];
    for (i = 0; i < @U@_CTL_NT; ++i) ctl_t[i] = s->ctl_t[i];
    if (!bad && (par->eps != s->par.eps || par->b0 != s->par.b0))
        bad = obs_retune(obs_t, par->eps, par->b0) != 0;
    if (!bad && (par->k1 != s->par.k1 || par->k2 != s->par.k2 || par->b0 != s->par.b0))
        bad = ctl_retune(ctl_t, par->k1, par->k2, par->b0) != 0;
    if (bad) {
        s->fault = (uint8_t)(s->fault | @U@_FAULT_PARAMS);
        return -1;
    }
    obs_derive(obs_t);
    ctl_derive(ctl_t);
    for (i = 0; i < @U@_OBS_NT; ++i) s->obs_t[i] = obs_t[i];
    for (i = 0; i < @U@_CTL_NT; ++i) s->ctl_t[i] = ctl_t[i];
    s->par = *par;
    return 0;
}

@P@_real @P@_step(@P@_state *s, @P@_real y, @P@_real theta_d, @P@_real omega_d,
                  @P@_real accel_d)
{
    esoarm_real ref[3];
    esoarm_real raw, u, emf, applied, drive, duty, input;
    uint8_t first = 0;
    if (!ISFINITE(y)) {
        s->fault = (uint8_t)(s->fault | @U@_FAULT_MEASUREMENT);
        return s->u;
    }
    if (!ISFINITE(theta_d) || !ISFINITE(omega_d) || !ISFINITE(accel_d)) {
        s->fault = (uint8_t)(s->fault | @U@_FAULT_REFERENCE);
        return s->u;
    }
    ref[0] = theta_d; ref[1] = omega_d; ref[2] = accel_d;
    if (!s->started) {
        obs_initialize(s->z, y);
        ctl_initialize(s->c, y);
        s->started = 1;
        first = 1;
    }
    obs_estimate(s->obs_t, s->z, y, s->zhat);
    raw = ctl_control(s->ctl_t, s->c, s->zhat, y, ref, first);
    u = act_saturate(raw, ACT_P[0]);
    emf = act_back_emf(s->zhat[1]);
    act_actuate(u, emf, &applied, &drive, &duty);
#if ACT_FF_N > 0
    /* the learned table: in the drive and the duty, not in what the observer is fed */
    act_drive(act_saturate(u + act_feedforward(s->zhat[0]), ACT_P[0]), emf, &drive, &duty);
#endif
    if (!ISFINITE(u) || !ISFINITE(applied)) {  /* the state no longer holds a number */
        s->fault = (uint8_t)(s->fault | @U@_FAULT_STATE);
        return s->u;
    }
    s->u = u; s->applied = applied; s->drive = drive; s->duty = duty;
    /* the observer's input: the applied command, or (actuator.observer_sees = "commanded",
     * the paper's ESO) the controller's command before saturation; 0 while the gate at an
     * end stop holds (actuator.stop_gate) */
    input = plant_observer_input(s->zhat, ACT_SEES ? raw : applied);
    if (act_gated(y, input)) input = R(0.0);
    obs_advance(s->obs_t, s->z, s->zhat, y, input);
    return u;
}
"""


def write_sources(gen: Generated, out: Path) -> list[Path]:
    """Write the generated files (controller and reference, ``.h`` and ``.c``) into ``out``.

    Parameters
    ----------
    gen : Generated
        From :func:`generate`.
    out : Path
        Destination folder (created).

    Returns
    -------
    list of Path
        The files written, the controller's header and source first.
    """
    from esoarm._io import atomic_path

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, text in gen.files.items():
        path = out / name
        with atomic_path(path) as tmp:
            Path(tmp).write_text(text, encoding="utf-8")
        paths.append(path)
    return paths
