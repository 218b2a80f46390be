"""Commissioning a rig in one command: the path from a new rig to an on-board controller.

:class:`Commission` runs the steps a person follows on a new rig, each through the
study function that does it on its own (nothing is computed twice here):

1. ``excite`` -- a multisine within the torque limit, with the angle limit and every safety
   check of ``esoarm run``
   (:class:`~esoarm.studies.identification.experiment.excitation.ExcitationController`
   through :func:`esoarm.hardware.realtime.run_rig`, as ``esoarm excite --port``);
2. ``identify`` -- the grey-box fit (:func:`esoarm.studies.identification.identify.identify`)
   with its refusals (a fit that failed, or one it does not trust);
3. ``design`` -- the noise budget and the recommended observer kind and ε for a
   perturbation-estimate bandwidth (:func:`esoarm.studies.frequency.noise.recommend_eps`), and
   the prediction: ``esoarm simulate`` of the design on the identified twin;
4. ``codegen`` -- the generated C for the Uno (:func:`esoarm.codegen.generate.generate`) with
   the observer sums that fit its period (:func:`esoarm.codegen.onboard.choose_sums`, timed by
   PIL);
5. ``flash`` -- the on-board firmware built (:func:`esoarm.codegen.onboard.onboard_firmware`)
   and put on the board: on ``--hil`` loaded into the simulated Uno; on a port, the board
   must answer with the design's hash (CHIP_INFO) or the step says how to flash it;
6. ``run`` -- the reference trajectory on board (``run_rig(..., onboard=True)``), measured.

Each step writes its result to the work directory (``NN-step.json`` and its data files)
with a key of its inputs; ``resume=True`` takes a step from its file when the key matches,
so an interrupted or refused commissioning continues where it stopped.  A refusal raises
:class:`CommissionRefused` with the reason and what to change.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from esoarm.scenario import Scenario, ScenarioError, load_scenario

__all__ = ["AGREEMENT", "STEPS", "Commission", "CommissionOptions", "CommissionRefused",
           "check_options"]

#: The steps, in order (their files are ``NN-name.json`` in the work directory).
STEPS = ("excite", "identify", "design", "codegen", "flash", "run")
#: Measured RMS error and RMS Δu must be within this fraction of the predicted ones.
AGREEMENT = 0.25
#: Attempts of a run on the simulated board that a watchdog ended (a busy machine).
HIL_ATTEMPTS = 3
#: The design takes the least chatter among the observer kinds whose disturbance -> error
#: peak is within this factor of the smallest one.
PEAK_RATIO = 1.5


class CommissionRefused(RuntimeError):
    """A step refused to go on: ``reason`` and what to change (``advice``)."""

    def __init__(self, step: str, reason: str, advice: str) -> None:
        super().__init__(f"{step}: {reason}")
        self.step, self.reason, self.advice = step, reason, advice


@dataclass(frozen=True)
class CommissionOptions:
    """What the person gives.

    Attributes
    ----------
    scenario : str
        Built-in name or TOML path: the rig's nominal model (and on ``hil`` the twin that
        stands for the rig).
    overrides : tuple of str
        ``KEY=VALUE`` as given to ``--set``.
    workdir : Path
        One file per step.
    port : str or None
        Serial device of the rig; None with ``hil``.
    hil : bool
        The rig is the simulated Uno with the scenario's twin on its pins.
    bandwidth : float or None
        Perturbation-estimate bandwidth [rad/s] to design for; None: proposed.
    observer_kind : str or None
        Take this kind's recommendation instead of the one with the least chatter.
    amplitude : float
        RMS torque of the excitation multisine [N·m].
    excite_seconds : float
        Length of the excitation [s].
    angle_limit : float
        Largest |θ| any step may reach [rad].
    baud : int
        Line rate of the rig's stock firmware [bit/s] (the on-board build uses 1 Mbit/s).
    resume : bool
        Take steps from their files when their inputs match.
    """

    scenario: str
    overrides: tuple[str, ...]
    workdir: Path
    port: str | None = None
    hil: bool = False
    bandwidth: float | None = None
    observer_kind: str | None = None
    amplitude: float = 0.2
    excite_seconds: float = 60.0
    angle_limit: float = 1.5
    baud: int = 115200
    resume: bool = False


def _key(*parts: object) -> str:
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


class Commission:
    """The commissioning of one rig (see the module docstring).

    Parameters
    ----------
    opts : CommissionOptions
    say : callable
        Receives one line per step as it starts and ends.
    """

    def __init__(self, opts: CommissionOptions, say: Callable[[str], None] = print) -> None:
        self.opts = opts
        self.say = say
        self.rig = load_scenario(opts.scenario, list(opts.overrides))
        self.dir = opts.workdir
        self.results: dict[str, dict[str, Any]] = {}
        self.status: dict[str, dict[str, Any]] = {}
        self._prev_key = _key(self.rig.model_dump_json(), opts.port, opts.hil)

    # -- the step machinery -------------------------------------------------------------
    def _file(self, step: str) -> Path:
        return self.dir / f"{STEPS.index(step) + 1:02d}-{step}.json"

    def _step(self, step: str, inputs: dict[str, Any],
              work: Callable[[], dict[str, Any]]) -> dict[str, Any]:
        key = _key(self._prev_key, inputs)
        path = self._file(step)
        if self.opts.resume and path.exists():
            try:
                saved = json.loads(path.read_text(encoding="utf-8"))
            except ValueError:
                saved = {}
            if saved.get("key") == key:
                self.say(f"{step}: resumed from {path.name}")
                self.results[step] = saved["result"]
                self.status[step] = {"status": "resumed", "file": path.name,
                                     "elapsed_s": saved.get("elapsed_s")}
                self._prev_key = key
                return saved["result"]
        self.say(f"{step}: ...")
        t0 = time.perf_counter()
        result = _jsonable(work())
        elapsed = time.perf_counter() - t0
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps({"step": step, "key": key, "elapsed_s": elapsed,
                                   "result": result}, indent=1), encoding="utf-8")
        tmp.replace(path)
        self.results[step] = result
        self.status[step] = {"status": "done", "file": path.name, "elapsed_s": elapsed}
        self._prev_key = key
        self.say(f"{step}: done in {elapsed:.1f} s")
        return result

    def run(self) -> dict[str, Any]:
        """Every step in order; returns :meth:`summary`.

        Raises
        ------
        CommissionRefused
            A step refused (the files of the steps before it stay).
        ScenarioError
            Bad input found by a study function (an unknown key, a plan out of range).
        """
        self.dir.mkdir(parents=True, exist_ok=True)
        self._excite()
        self._identify()
        self._design()
        self._codegen()
        self._flash()
        self._run()
        return self.summary()

    # -- 1. excitation --------------------------------------------------------------------
    def _limits(self, onboard: bool = False) -> Any:
        from esoarm.hardware.realtime import SafetyLimits

        # the simulated board runs slower than real time on a busy machine: its samples may
        # come late by far more than a rig's, so the host's sample watchdog is wider there
        return SafetyLimits(angle_limit=self.opts.angle_limit, max_jump=0.5,
                            watchdog=5.0 if self.opts.hil else 0.25,
                            max_error=0.5 if onboard else math.inf)

    def _drive(self, scn: Scenario, elf: Path | None, log: Path, name: str, limits: Any,
               advice: str, baud: int | None = None,
               controller: Callable[[], Any] | None = None, **run_kwargs: Any) -> Any:
        """One run of ``scn`` on the rig (on ``hil``: ``elf`` on the simulated Uno).

        On ``hil`` a run that a watchdog ended (the simulated board's 100 ms command or
        heartbeat watchdog, or the host's) is tried again, up to :data:`HIL_ATTEMPTS` times
        in all, and said: the simulated chip's time runs at the wall clock's pace while the
        host owes it an answer, so a host stalled by a busy machine trips it (measured: at
        sample 626 of the excitation at a load of 14 on 2 cores).  ``controller`` makes a
        fresh per-sample controller for each attempt.
        """
        attempts = HIL_ATTEMPTS if self.opts.hil else 1
        for attempt in range(1, attempts + 1):
            kwargs = dict(run_kwargs)
            if controller is not None:
                kwargs["controller"] = controller()
            try:
                return self._drive_once(scn, elf, log, name, limits, advice, baud, **kwargs)
            except CommissionRefused as exc:
                if attempt == attempts or "watchdog" not in exc.reason:
                    raise
                self.say(f"{name}: {exc.reason.split(': stop sent')[0]} on the simulated board "
                         f"(the machine is busy: the host answered late); again, attempt "
                         f"{attempt + 1} of {attempts}")
        raise AssertionError("unreachable")  # pragma: no cover

    def _drive_once(self, scn: Scenario, elf: Path | None, log: Path, name: str, limits: Any,
                    advice: str, baud: int | None = None, **run_kwargs: Any) -> Any:
        """One attempt of :meth:`_drive`."""
        from esoarm.hardware.link import LinkError, SerialLink
        from esoarm.hardware.realtime import RigFault, run_rig

        board = None
        if self.opts.hil:
            from esoarm.studies.commission.board import SimulatedBoard

            assert elf is not None
            try:
                board = SimulatedBoard(self.opts.scenario, self.opts.overrides, elf,
                                       self.dir / f"{name}-board.txt")
            except RuntimeError as exc:
                raise CommissionRefused(name, str(exc), "check the simulator (esoarm hil "
                                        "SCENARIO)") from None
            port = board.path
        else:
            assert self.opts.port is not None
            port = self.opts.port
        try:
            link = SerialLink(port, baudrate=baud or self.opts.baud)
        except LinkError as exc:
            if board is not None:
                board.close(5)
            raise CommissionRefused(name, str(exc), "check the port and that the board is "
                                    "powered (esoarm run --port PATH answers?)") from None
        try:
            return run_rig(scn, link, log, limits, **run_kwargs)
        except RigFault as exc:
            if "watchdog" in str(exc):
                advice = ("a sample or a command came too late: check the link to the board "
                          "(USB cable, hub) and run the same command again with --resume")
            raise CommissionRefused(name, str(exc), advice) from None
        except LinkError as exc:
            raise CommissionRefused(name, str(exc), "check the link to the board") from None
        finally:
            link.close()
            if board is not None:
                board.close()

    def _excite(self) -> dict[str, Any]:
        from esoarm.studies.identification.experiment.excitation import (
            ExcitationController,
            ExcitationPlan,
        )

        rig, o = self.rig, self.opts
        plan = ExcitationPlan(duration=o.excite_seconds, amplitude=o.amplitude)
        plan.check(rig.sample_time)
        log = self.dir / "01-excite.csv"

        def work() -> dict[str, Any]:
            from esoarm.hardware.hil.build import firmware_elf

            elf = None
            if o.hil:
                from esoarm.hardware.emulator import encoder_counts_per_rev

                period_us = round(1e6 * rig.sample_time)
                ppr = encoder_counts_per_rev(rig) // 4
                settings = {k: v for k, v, default in (("SAMPLE_PERIOD_US", period_us, 20000),
                                                       ("ENCODER_PPR", ppr, 600))
                            if v != default}
                elf = firmware_elf("l298n", settings=settings)
            s = self._drive(rig, elf, log, "excite", self._limits(),
                            "lower --amplitude, or raise --angle-limit if the arm is safe there; "
                            "check the sign of motor and encoder (docs: Running esoarm on a "
                            "rig, First run)",
                            controller=lambda: ExcitationController(rig, plan))
            rows = np.genfromtxt(log, delimiter=",", names=True)
            return {"log": log.name, "samples": s.samples, "lost_samples": s.lost_samples,
                    "rms_u": s.rms_u, "max_abs_u": float(np.nanmax(np.abs(rows["u"]))),
                    "max_abs_theta": float(np.nanmax(np.abs(rows["theta"]))),
                    "torque_limit": rig.actuator.torque_limit, "angle_limit": o.angle_limit,
                    "amplitude": o.amplitude, "seconds": o.excite_seconds,
                    "f_min": plan.f_min, "f_max": plan.f_max, "tones": plan.n_tones}

        return self._step("excite", {"plan": plan.__dict__, "angle": o.angle_limit}, work)

    # -- 2. identification ----------------------------------------------------------------
    def _identify(self) -> dict[str, Any]:
        rig = self.rig
        toml = self.dir / "02-fitted.toml"

        def work() -> dict[str, Any]:
            from esoarm.plants.actuator import motor_of
            from esoarm.studies.identification.data import read_ident_log
            from esoarm.studies.identification.identify import FitFailed, identify
            from esoarm.studies.identification.report import scenario_toml

            log = read_ident_log(self.dir / "01-excite.csv", rig.actuator.torque_limit,
                                 motor_of(rig))
            try:
                res = identify(rig, [log])
            except FitFailed as exc:
                raise CommissionRefused("identify", str(exc), "record a richer experiment: "
                                        "raise --amplitude or --excite-seconds") from None
            why = res.untrustworthy()
            if why:
                raise CommissionRefused("identify", why, "raise --amplitude or "
                                        "--excite-seconds, or hold a parameter with --set")
            toml.write_text(scenario_toml(res, res.fitted_scenario()), encoding="utf-8")
            out = res.to_json()
            out["fitted_scenario"] = toml.name
            return out

        return self._step("identify", {}, work)

    def fitted(self) -> Scenario:
        """The identified scenario (from its file)."""
        return load_scenario(self.dir / "02-fitted.toml")

    # -- 3. design and prediction ---------------------------------------------------------
    def _budget_scenario(self, scn: Scenario) -> tuple[Scenario, list[str]]:
        """The scenario the noise budget can model, and what was changed for it, in words."""
        from esoarm.scenario.schema import build

        notes = []
        data = scn.to_dict()
        if data.get("motor") is not None:
            data.pop("motor")
            notes.append("the noise budget models the torque loop: the motor's back-EMF "
                         "compensation, deadband and PWM steps are left out of it")
        q = scn.sensor.resolution_deg
        sigma = math.hypot(scn.sensor.noise_deg, q / math.sqrt(12.0))
        data["sensor"]["noise_deg"] = sigma
        notes.append(f"encoder noise budgeted as {sigma:.3g}° RMS: sensor.noise_deg = "
                     f"{scn.sensor.noise_deg:.3g}° of the identified scenario (identify writes "
                     "its noise estimate only when the residual is sensor noise) and the "
                     f"quantization q/√12 of q = {q:g}° (white)")
        return build(data, {}, source=f"scenario '{scn.name}'"), notes

    def _design(self) -> dict[str, Any]:
        o = self.opts
        toml = self.dir / "03-design.toml"
        predicted_csv = self.dir / "03-predicted.csv"

        def work() -> dict[str, Any]:
            from esoarm.engines.simulation import simulate
            from esoarm.studies.frequency.noise import (
                noise_budget,
                perturbation_bandwidth,
                recommend_eps,
            )

            fitted = self.fitted()
            nyquist = math.pi / fitted.sample_time
            proposed = o.bandwidth is None
            bw = perturbation_bandwidth(fitted) if proposed else float(o.bandwidth)  # type: ignore[arg-type]
            if not (0 < bw < nyquist):
                raise CommissionRefused("design", f"--bandwidth {bw:g} rad/s is not below the "
                                        f"Nyquist frequency π/Ts = {nyquist:.4g} rad/s",
                                        "give a lower --bandwidth (or raise sensor.rate_hz)")
            budget_scn, notes = self._budget_scenario(fitted)
            recs = recommend_eps(budget_scn, bw)
            if not recs:
                raise CommissionRefused(
                    "design", f"no observer kind reaches a perturbation-estimate bandwidth of "
                    f"{bw:.4g} rad/s below the Nyquist frequency ({nyquist:.4g} rad/s) with a "
                    "stable loop", "give a lower --bandwidth")
            # The least chatter among the kinds that reject disturbances about as well as the
            # best one: equal f -> z3 bandwidths are not equal rejection, and a kind with
            # several times the disturbance -> error peak turns every model error the
            # identification left into tracking error (uno-rig: the cascade ESO, 3.3x the
            # linear one's peak, tracked 11-39 % worse on the rig than predicted).
            least = min(recs, key=lambda r: r.disturbance_peak)
            fair = [r for r in recs if r.disturbance_peak <= PEAK_RATIO * least.disturbance_peak]
            best = min(fair, key=lambda r: r.budget.rms_du)
            for r in recs:
                if r is not best and r.budget.rms_du < best.budget.rms_du:
                    notes.append(
                        f"the {r.kind} ESO (ε = {r.eps:.4g} s) chatters less (noise RMS Δu "
                        f"{r.budget.rms_du:.3g} against {best.budget.rms_du:.3g} N·m) but has "
                        f"{r.disturbance_peak / best.disturbance_peak:.2g}× the disturbance → "
                        f"error peak: not taken (--observer-kind {r.kind} takes it)")
            if o.observer_kind is not None:
                chosen = [r for r in recs if r.kind == o.observer_kind]
                if not chosen:
                    raise CommissionRefused(
                        "design", f"observer.kind = {o.observer_kind} does not reach "
                        f"{bw:.4g} rad/s with a stable loop", "leave out --observer-kind, or "
                        "give another --bandwidth")
                best = chosen[0]
            design = fitted.with_overrides({"name": f"{self.rig.name}-commissioned",
                                            "observer.kind": best.kind,
                                            "observer.eps": best.eps})
            toml.write_text(f"# esoarm commission: the identified rig with the observer "
                            f"designed for {bw:.4g} rad/s\n" + design.to_toml(),
                            encoding="utf-8")
            design = load_scenario(toml)  # what every later step reads
            res = simulate(design)
            if res.diverged:
                raise CommissionRefused("design", "the design diverges on the identified twin "
                                        "(esoarm simulate)", "give a lower --bandwidth")
            m = res.metrics
            table = np.column_stack([res.t, res.theta[:, 0] if res.theta.ndim > 1 else res.theta,
                                     res.theta_ref if res.theta_ref.ndim == 1
                                     else res.theta_ref[:, 0],
                                     res.u if res.u.ndim == 1 else res.u[:, 0]])
            np.savetxt(predicted_csv, table, delimiter=",", header="t,theta,theta_ref,u",
                       comments="")
            budget = noise_budget(budget_scn.with_overrides({"observer.kind": best.kind,
                                                             "observer.eps": best.eps}))
            return {
                "bandwidth": bw, "bandwidth_proposed": proposed,
                "bandwidth_source": ("proposed: the perturbation-estimate bandwidth of the "
                                     f"scenario's own observer ({fitted.observer.kind}, ε = "
                                     f"{fitted.observer.eps:g} s)") if proposed
                else "given (--bandwidth)",
                "nyquist": nyquist, "observer_kind": best.kind, "eps": best.eps,
                "recommendations": [{"kind": r.kind, "eps": r.eps, "bandwidth": r.bandwidth,
                                     "disturbance_peak": r.disturbance_peak,
                                     **r.budget.to_dict()} for r in recs],
                "noise_budget": budget.to_dict(), "notes": notes,
                "scenario": toml.name, "predicted_series": predicted_csv.name,
                "predicted": {"rms_error": m["rms_error"], "rms_du": m["rms_du"],
                              "rms_u": m["rms_u"], "max_abs_error": m["max_abs_error"],
                              "samples": len(res.t)},
            }

        return self._step("design", {"bandwidth": o.bandwidth, "kind": o.observer_kind}, work)

    def design(self) -> Scenario:
        """The designed scenario (from its file)."""
        return load_scenario(self.dir / "03-design.toml")

    # -- 4. code generation -----------------------------------------------------------------
    def _codegen(self) -> dict[str, Any]:
        out_dir = self.dir / "04-codegen"

        def work() -> dict[str, Any]:
            from esoarm.codegen import CodegenError, generate, write_sources
            from esoarm.codegen.onboard import choose_sums

            design = self.design()
            try:
                choice = choose_sums(design)
            except CodegenError as exc:
                raise CommissionRefused("codegen", str(exc), "lower sensor.rate_hz "
                                        "(--set sensor.rate_hz=...)") from None
            gen = generate(design, "avr", "float32", choice.compensated)
            paths = write_sources(gen, out_dir)
            return {"target": "avr", "precision": "float32", "observer_sums": choice.name,
                    "why": choice.reason, "sha256": gen.digest,
                    "files": [str(p.relative_to(self.dir)) for p in paths]}

        return self._step("codegen", {}, work)

    # -- 5. flashing ----------------------------------------------------------------------
    def _flash(self) -> dict[str, Any]:
        def work() -> dict[str, Any]:
            from esoarm.codegen.avr import image_sizes
            from esoarm.codegen.generate import scenario_hash
            from esoarm.codegen.onboard import BAUD, onboard_firmware

            design = self.design()
            sums = self.results["codegen"]["observer_sums"]
            elf = onboard_firmware(design, compensated=sums == "compensated")
            flash, ram = image_sizes(elf, "avr-size")
            digest = scenario_hash(design)[:8]
            out: dict[str, Any] = {"elf": str(elf), "hex": str(elf.with_suffix(".hex")),
                                   "flash_bytes": flash, "ram_bytes": ram, "baud": BAUD,
                                   "hash": digest}
            if self.opts.hil:
                out["board"] = ("the simulated Uno (simavr ATmega328P, 16 MHz): the image is "
                                "loaded when the run starts")
                return out
            out.update(self._flash_port(elf.with_suffix(".hex"), digest, BAUD,
                                        round(1e6 * design.sample_time)))
            return out

        return self._step("flash", {}, work)

    def _board_hash(self, baud: int) -> str:
        """The scenario hash of the on-board firmware on the port ("" when none answers)."""
        from esoarm.hardware.link import LinkError, SerialLink

        assert self.opts.port is not None
        try:
            link = SerialLink(self.opts.port, baudrate=baud)
        except LinkError as exc:
            raise CommissionRefused("flash", str(exc), "check the port") from None
        try:
            info = link.handshake()
            return link.chip_info().scenario_hash if info.onboard else ""
        except LinkError:  # the rig firmware at another line rate, or a board in its bootloader
            return ""
        finally:
            link.close()

    def _flash_port(self, hex_path: Path, expected: str, baud: int, period_us: int
                    ) -> dict[str, Any]:
        """Put the design's firmware on the Uno at the port.

        Already there (the port answers with the design's hash), or written with avrdude
        through the Uno's bootloader and its hash read back (:func:`esoarm.hardware.flash.flash`).
        """
        port = self.opts.port
        assert port is not None
        by_hand = (f"flash {hex_path} by hand (make -C firmware upload ONBOARD="
                   f"{self.dir / '04-codegen'} SAMPLE_PERIOD_US={period_us} BAUD={baud} "
                   f"PORT={port}), then run the same command again with --resume")
        on_board = self._board_hash(baud)
        if on_board == expected:
            return {"board": f"{port}: already runs the design's firmware (hash {on_board})"}
        from esoarm.hardware.flash import NotABootloader, flash
        from esoarm.hardware.hil.build import ToolchainMissing

        try:
            rep = flash(hex_path, port, expected, baud)
        except NotABootloader as exc:
            raise CommissionRefused("flash", str(exc), by_hand) from None
        except (RuntimeError, ToolchainMissing, OSError) as exc:
            raise CommissionRefused("flash", str(exc), by_hand) from None
        if not rep.ok:
            raise CommissionRefused("flash", f"after the write the board on {port} reports the "
                                    f"scenario hash {rep.hash_read}, not the design's "
                                    f"{expected}", by_hand)
        return {"board": f"{port}: written with avrdude ({rep.flash_bytes} bytes verified, "
                         f"signature {rep.signature}) in {rep.seconds:.1f} s; the firmware "
                         f"reports the design's hash {rep.hash_read}"}

    # -- 6. the on-board run ------------------------------------------------------------------
    def _run(self) -> dict[str, Any]:
        log = self.dir / "06-run.csv"

        def work() -> dict[str, Any]:
            from esoarm.codegen.onboard import BAUD

            design = self.design()
            elf = Path(self.results["flash"]["elf"])
            notices: list[str] = []
            s = self._drive(design, elf, log, "run", self._limits(onboard=True),
                            "check the rig against the identified model (esoarm replay "
                            "06-run.csv), lower --bandwidth, or raise the limits", baud=BAUD,
                            onboard=True, notice=notices.append)
            return {"log": log.name, "notices": notices, **s.to_dict()}

        return self._step("run", {}, work)

    # -- the outcome ------------------------------------------------------------------------
    def summary(self) -> dict[str, Any]:
        """One JSON object: the steps, what was identified, designed, predicted and measured."""
        r = self.results
        ident = r.get("identify", {})
        design = r.get("design", {})
        predicted = design.get("predicted")
        run = r.get("run")
        measured = None if run is None else {
            k: run.get(k) for k in ("rms_error", "rms_du", "rms_u", "max_abs_error", "samples",
                                    "lost_samples", "deadline_misses", "observer_sums",
                                    "stream_every")}
        agreement = None
        if predicted and measured:
            ratios = {k: (measured[k] / predicted[k] - 1) if predicted[k] else None
                      for k in ("rms_error", "rms_du")}
            agreement = {"relative": ratios, "limit": AGREEMENT,
                         "rms_error_ok": ratios["rms_error"] is not None
                         and abs(ratios["rms_error"]) <= AGREEMENT,
                         "rms_du_ok": ratios["rms_du"] is not None
                         and abs(ratios["rms_du"]) <= AGREEMENT}
        return _jsonable({
            "scenario": self.rig.name, "workdir": str(self.dir),
            "rig": "simulated Uno (--hil)" if self.opts.hil else f"port {self.opts.port}",
            "steps": self.status,
            "excitation": r.get("excite"),
            "identified": None if not ident else {
                "parameters": {k: {"value": v["value"], "ci95": v["ci95"], "unit": v["unit"],
                                   "fitted": v["fitted"],
                                   **{w: v[w] for w in ("withheld", "advice") if v.get(w)}}
                               for k, v in ident["parameters"].items()},
                "fit_percent": ident["fit"]["fit_percent"],
                "validation_fit_percent": ident["validation"].get("fit_percent"),
                "residual_white": ident["validation"].get("whiteness", {}).get("white"),
                "poorly_identifiable": ident["poorly_identifiable"],
                "at_bound": ident["at_bound"], "noise": ident["noise"],
                "scenario": ident.get("fitted_scenario")},
            "design": None if not design else {
                k: design[k] for k in ("observer_kind", "eps", "bandwidth", "bandwidth_source",
                                       "nyquist", "recommendations", "noise_budget", "notes",
                                       "scenario")},
            "codegen": r.get("codegen"), "flash": r.get("flash"),
            "predicted": predicted, "measured": measured, "agreement": agreement,
        })


def check_options(opts: CommissionOptions) -> None:
    """Bad input, before any work: raise :class:`ScenarioError` with one line."""
    if opts.hil == (opts.port is not None):
        raise ScenarioError("give exactly one of --port PATH (a rig) or --hil (the simulated "
                            "Uno with the scenario's twin)")
    for name, value in (("--amplitude", opts.amplitude), ("--excite-seconds",
                                                          opts.excite_seconds),
                        ("--angle-limit", opts.angle_limit)):
        if not (math.isfinite(value) and value > 0):
            raise ScenarioError(f"{name} {value:g}: must be a finite number > 0")
    if opts.bandwidth is not None and not (math.isfinite(opts.bandwidth) and opts.bandwidth > 0):
        raise ScenarioError(f"--bandwidth {opts.bandwidth:g}: must be a positive frequency "
                            "[rad/s]")
