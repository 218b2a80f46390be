"""Does fixed point earn its place on the ATmega328P?  A Q-format linear ESO + FLC, measured.

Run:  python benchmarks/bench_fixed.py [--update docs/on-the-chip.md]

The experiment: ``test-1`` (lever arm, ideal torque source, linear ESO "euler",
FLC with ESO compensation), the generated float32 step (plain and compensated
observer sums) against the same step with the observer *and* the control law in
32-bit fixed point, each run processor in the loop on simavr's ATmega328P
(:class:`esoarm.codegen.avr.AvrChip`, cycles between the GPIOR0 writes) in
lockstep with the twin and the Python float64 reference, at 50 Hz and 1 kHz.

The fixed-point step (written here, not a product feature):

* Q-formats: every quantity is an ``int32`` with a scale 2^s chosen per state
  from the float64 run itself: s = 31 − ceil(log2(4 · max |x|)), a margin of 4
  over the largest value of that state (and of the reference term it is
  compared with) over the scenario's run; the command in the format of
  twice the torque limit.  That choice is what a designer would have to make
  per scenario (a bound from the run, not a proof that nothing overflows).
* Products: ``(int64) a · C >> sh`` rounded to nearest, C the design constant in
  the output's format, sh a multiple of 8 (byte moves on the AVR), C holding at
  least 24 significant bits.
* The same Euler ESO (eq. 8) and FLC (eq. 14-16) as the float code:
  U = I0 (θ̈d − Z3) − I0 k1 (Z2 − θ̇d) − I0 k2 (Z1 − θd), saturated;
  Z1 += Ts Z2 + Ts β1 E, Z2 += Ts Z3 + Ts b0 U + Ts β2 E, Z3 += Ts β3 E.
* Its input y and the reference θd, θ̇d, θ̈d stay float (the reference is the
  generated float32 code) and are converted (4 float -> int conversions), the
  command is converted back (1): on a rig y would be the encoder's count and u
  a duty, both integers, so the table also gives the step without the
  conversions of y and u (estimated by subtracting their measured cost).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

import numpy as np
from doc_block import write_block

from esoarm.codegen.avr import AvrChip
from esoarm.codegen.generate import Generated, generate
from esoarm.codegen.host import HostChip
from esoarm.codegen.lockstep import LockstepRun, lockstep
from esoarm.kinds import kinds_of
from esoarm.scenario import Scenario, load_scenario

MARGIN = 4.0


def _scale(peak: float) -> int:
    """s such that MARGIN · peak fits an int32 scaled by 2^s."""
    return 31 - math.ceil(math.log2(MARGIN * max(peak, 1e-9)))


def _constant(c: float, s_in: int, s_out: int, name: str) -> tuple[str, int]:
    """``#define`` of C, the product's shift sh: out = (a · C) >> sh."""
    m = c * 2.0 ** (s_out - s_in)
    for sh in (48, 40, 32, 24, 16, 8):
        if abs(m) * 2.0 ** sh < 2.0 ** 31:
            k = round(m * 2.0 ** sh)
            if abs(k) < 2 ** 23:
                raise SystemExit(f"{name}: only {abs(k).bit_length()} bits")
            return f"#define {name} {k}L\n#define {name}_SH {sh}\n", sh
    raise SystemExit(f"{name} does not fit")  # pragma: no cover


def fixed_source(scn: Scenario, gen: Generated, peaks: dict[str, float],
                 product: int = 0) -> tuple[str, str]:
    """The generated float32 source with the step replaced by the Q-format one."""
    kinds = kinds_of(scn)
    plant = kinds.plant.design(scn)
    obs = kinds.observer.design(scn, plant, scn.sample_time).vector[1:]
    ctl = kinds.controller.design(scn, plant, scn.sample_time).vector[1:]
    if obs[0] != 0.0 or ctl[4] != 0.0:
        raise SystemExit("the fixed-point step covers the euler ESO with ESO compensation")
    ts, b0, b1, b2, b3 = obs[1], obs[2], obs[3], obs[4], obs[5]
    k1, k2, i0, limit = ctl[0], ctl[1], ctl[2], ctl[5]
    s1, s2, s3 = _scale(peaks["z1"]), _scale(peaks["z2"]), _scale(peaks["z3"])
    su = _scale(limit * MARGIN / 4.0 * 2.0)  # twice the torque limit
    text = (f"/* Q-formats: z1 Q{31 - s1}.{s1}, z2 Q{31 - s2}.{s2}, z3 Q{31 - s3}.{s3}, "
            f"u Q{31 - su}.{su} */\n")
    for name, c, si, so in (("C_TS12", ts, s2, s1), ("C_E1", ts * b1, s1, s1),
                            ("C_TS23", ts, s3, s2), ("C_U2", ts * b0, su, s2),
                            ("C_E2", ts * b2, s1, s2), ("C_E3", ts * b3, s1, s3),
                            ("C_K3", i0, s3, su), ("C_K2", i0 * k1, s2, su),
                            ("C_K1", i0 * k2, s1, su)):
        text += _constant(c, si, so, name)[0]
    text += f"""#define S1 {2.0 ** s1!r}f
#define S2 {2.0 ** s2!r}f
#define S3 {2.0 ** s3!r}f
#define INV_SU {2.0 ** -su!r}f
#define U_LIM {round(limit * 2.0 ** su)}L
#if Q_PRODUCT == 0  /* the compiler's 64-bit product (avr-gcc: __muldi3) */
#define QMUL(a, c) ((int32_t)(((int64_t)(a) * (c) + ((int64_t)1 << (c##_SH - 1))) >> c##_SH))
#else  /* four 16 x 16 -> 32 products (the AVR's MUL), magnitudes, rounded half away */
static inline __attribute__((always_inline)) int32_t qmul(int32_t a, int32_t c, uint8_t sh)
{{
    uint8_t neg = (a < 0) != (c < 0);
    uint32_t x = a < 0 ? -(uint32_t)a : (uint32_t)a;
    uint32_t y = c < 0 ? -(uint32_t)c : (uint32_t)c;
    uint16_t xh = (uint16_t)(x >> 16), xl = (uint16_t)x, yh = (uint16_t)(y >> 16);
    uint16_t yl = (uint16_t)y;
    uint32_t ll = (uint32_t)xl * yl, lh = (uint32_t)xl * yh, hl = (uint32_t)xh * yl;
    uint32_t hh = (uint32_t)xh * yh, mid = lh + hl, lo, hi, r;
    hi = hh + (mid >> 16) + (mid < lh ? 0x10000UL : 0UL);
    lo = ll + (mid << 16);
    hi += lo < ll;
    if (sh > 32) hi += 1UL << (sh - 33);
    else {{ uint32_t t = lo + (1UL << (sh - 1)); hi += t < lo; lo = t; }}
    r = sh >= 32 ? hi >> (sh - 32) : (hi << (32 - sh)) | (lo >> sh);
    return neg ? -(int32_t)r : (int32_t)r;
}}
#define QMUL(a, c) qmul((a), (c), c##_SH)
#endif
static int32_t Z1, Z2, Z3;

esoarm_real esoarm_step(esoarm_state *s, esoarm_real y, esoarm_real theta_d,
                        esoarm_real omega_d, esoarm_real accel_d)
{{
    int32_t yq = (int32_t)lrint(y * S1), e, u, d1, d2, d3;
    if (!s->started) {{ Z1 = yq; Z2 = 0; Z3 = 0; s->started = 1; }}
    /* FLC (eq. 14-16) on the estimate z = (Z1, Z2, Z3) */
    u = QMUL((int32_t)lrint(accel_d * S3) - Z3, C_K3)
        - QMUL(Z2 - (int32_t)lrint(omega_d * S2), C_K2)
        - QMUL(Z1 - (int32_t)lrint(theta_d * S1), C_K1);
    if (u > U_LIM) u = U_LIM;
    if (u < -U_LIM) u = -U_LIM;
    /* Euler ESO (eq. 8) */
    e = yq - Z1;
    d1 = QMUL(Z2, C_TS12) + QMUL(e, C_E1);
    d2 = QMUL(Z3, C_TS23) + QMUL(u, C_U2) + QMUL(e, C_E2);
    d3 = QMUL(e, C_E3);
    Z1 += d1; Z2 += d2; Z3 += d3;
    s->u = (esoarm_real)u * INV_SU;
    s->applied = s->drive = s->u;
    s->duty = R(0.0);
    return s->u;
}}
"""
    src = gen.source
    start = src.index("\n/* ---- plant kind")
    # the kinds' float step is left out (its design arrays stay, unused, and cost nothing);
    # the reference comes from the PIL shell as the step's arguments
    pragmas = ('#pragma GCC diagnostic ignored "-Wunused-variable"\n'
               '#pragma GCC diagnostic ignored "-Wunused-function"\n')
    init = ("void esoarm_init(esoarm_state *s)\n{\n    s->started = 0;\n"
            "    s->u = s->applied = s->drive = s->duty = R(0.0);\n}\n\n")
    pragmas += f"#define Q_PRODUCT {product}\n"
    return (pragmas + src[:start] + "\n/* ---- the Q-format step ---- */\n" + init + text,
            text)


def peaks_of(scn: Scenario) -> dict[str, float]:
    """max |ẑ_i| (and the reference it meets) over the float64 run (host build)."""
    chip = HostChip(generate(scn, "host", "float64"))
    zh = []
    orig = chip.step

    def step(y: float, ref: tuple[float, float, float] = (0.0, 0.0, 0.0)
             ) -> tuple[float, float, float]:
        out = orig(y, ref)
        zh.append(chip.last[3:6])
        return out

    chip.step = step  # type: ignore[method-assign]
    run = lockstep(scn, chip)
    z = np.abs(np.asarray(zh))
    refs = np.abs(np.asarray(run.theta_ref))
    return {"z1": float(max(z[:, 0].max(), refs.max())), "z2": float(z[:, 1].max()),
            "z3": float(z[:, 2].max())}


def without_observer(gen: Generated) -> Generated:
    """The float32 step with the observer reduced to ẑ = (y, 0, 0): what the observer costs
    is the difference (the controller then runs open loop on the twin)."""
    src = gen.source
    a = src.index("\n/* ---- observer kind")
    b = src.index("\n/* ---- controller kind")
    stub = """
#define OBS_NZ 6
static int obs_retune(esoarm_real T[], esoarm_real eps, esoarm_real b0)
{ (void)T; (void)eps; (void)b0; return 0; }
static void obs_initialize(esoarm_real z[], esoarm_real y) { z[0] = y; }
static void obs_estimate(const esoarm_real T[], const esoarm_real z[], esoarm_real y,
                         esoarm_real zhat[])
{ (void)T; (void)z; zhat[0] = y; zhat[1] = R(0.0); zhat[2] = R(0.0); }
static void obs_advance(const esoarm_real T[], esoarm_real z[], const esoarm_real zhat[],
                        esoarm_real y, esoarm_real u)
{ (void)T; (void)zhat; (void)u; z[0] = y; }
"""
    # the linear ESO's gain helper stays, unused by the stub
    pragma = '#pragma GCC diagnostic ignored "-Wunused-function"\n'
    return dataclasses.replace(gen, source=pragma + src[:a] + stub + src[b:])


def measure(scn: Scenario, gen: Generated) -> tuple[LockstepRun, AvrChip]:
    chip = AvrChip(gen)
    try:
        return lockstep(scn, chip), chip
    finally:
        chip.close()


def unit_costs() -> list[int]:
    """Cycles of one float -> int32 (lrint of y·S), int32 -> float (·2^-s), Q product
    ((int64) a·C >> 32, rounded), float32 product and float32 sum, measured (medians)."""
    scn = load_scenario("test-1", {"duration": 0.2})
    base = generate(scn, "avr", "float32", False)
    src = base.source
    start = src.index("\n/* ---- plant kind")
    body = ('#pragma GCC diagnostic ignored "-Wunused-variable"\n'
            '#pragma GCC diagnostic ignored "-Wunused-function"\n') + src[:start] + """
static volatile int32_t SINK;
static volatile esoarm_real SINKF;
void esoarm_init(esoarm_state *s) { s->started = 0; }
esoarm_real esoarm_step(esoarm_state *s, esoarm_real y, esoarm_real theta_d,
                        esoarm_real omega_d, esoarm_real accel_d)
{
    (void)theta_d; (void)omega_d; (void)accel_d;
#if MODE == 1
    SINK = (int32_t)lrint(y * 134217728.0f);
#elif MODE == 2
    SINKF = (esoarm_real)SINK * 7.450580596923828e-09f;
#elif MODE == 3
    SINK = (int32_t)(((int64_t)SINK * 1234567890L + ((int64_t)1 << 31)) >> 32);
#elif MODE == 4
    SINKF = SINKF * y;
#elif MODE == 5
    SINKF = SINKF + y;
#endif
    s->u = s->drive = s->duty = R(0.0);
    return y;
}
"""
    costs = []
    for mode in range(6):
        gen = dataclasses.replace(base, source=f"#define MODE {mode}\n" + body)
        chip = AvrChip(gen)
        try:
            for y in np.linspace(-1.0, 1.0, 20):
                chip.step(float(y))
            costs.append(int(np.median(chip.cycles)))
        finally:
            chip.close()
    return [c - costs[0] for c in costs[1:]]


def table() -> str:
    to_int, to_float, qmul, fmul, fadd = unit_costs()
    rows = ["| rate [Hz] | step | cycles min / median / max | % of the period at 1 kHz "
            "| flash [B] | max \\|Δu\\|/limit |", "|---|---|---|---|---|---|"]
    notes = []
    for rate in (50, 1000):
        scn = load_scenario("test-1", {"sensor.rate_hz": rate})
        peaks = peaks_of(scn)
        for label, comp, product in (
                ("float32, compensated sums", True, None), ("float32, plain sums", False, None),
                ("Q-format int32, the compiler's int64 product", None, 0),
                ("Q-format int32, four 16 × 16 products", None, 1)):
            gen = generate(scn, "avr", "float32", bool(comp))
            if product is not None:
                source, text = fixed_source(scn, gen, peaks, product)
                gen = dataclasses.replace(gen, source=source)
                if product == 0:
                    notes.append(f"{rate} Hz: "
                                 + text.splitlines()[0].strip("/* ").removeprefix("Q-formats: "))
            run, chip = measure(scn, gen)
            c = np.asarray(run.cycles)
            rows.append(f"| {rate} | {label} | {c.min()} / {int(np.median(c))} / {c.max()} | "
                        f"{100 * c.max() / 16000:.0f} % | {chip.flash_bytes} | "
                        f"{run.max_rel_du:.1e} |")
            print(rows[-1], flush=True)
            if comp is False:
                run0, chip0 = measure(scn, without_observer(gen))
                c0 = np.asarray(run0.cycles)
                rows.append(f"| {rate} | float32 plain, the observer left out (to size it: "
                            f"median {int(np.median(c)) - int(np.median(c0))} cycles) | "
                            f"{c0.min()} / {int(np.median(c0))} / {c0.max()} | "
                            f"{100 * c0.max() / 16000:.0f} % | {chip0.flash_bytes} | — |")
            if product == 0:
                worst = c.max() - to_int - to_float
                rows.append(f"| {rate} | the same, y and u as integers (its measured "
                            f"conversions, {to_int} + {to_float} cycles, subtracted) | — / "
                            f"{int(np.median(c)) - to_int - to_float} / {worst} | "
                            f"{100 * worst / 16000:.0f} % | — | — |")
    return "\n".join(rows + [
        "", "Q-formats (from the float64 run, margin 4): " + "; ".join(notes) + ".", "",
        f"Unit costs on the ATmega328P (avr-gcc 5.4 -Os, median cycles): one Q product "
        f"(int64) a·C >> 32 {qmul}, one float32 product {fmul}, one float32 sum {fadd}, "
        f"float -> int32 {to_int}, int32 -> float {to_float}."])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--update", type=Path, help="markdown file with bench_fixed markers")
    args = parser.parse_args()
    text = table()
    if args.update:
        write_block(args.update, "bench_fixed:table", text)
    else:
        print(text)


if __name__ == "__main__":
    main()
