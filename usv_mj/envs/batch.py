"""N episodes of a track task stepped together in one native call: the batch behind the vector environments.

::

    from usv_mj import envs
    batch = envs.load_batch("track", num_envs=64, seed=0, plant="analytic")   # the dm_env users' call
    ts = batch.reset()                     # a BatchTimeStep: arrays over the episodes
    ts = batch.step(thrust)                # thrust: (64, 2) [N, N m], as the dm_env's action
    ts.step_type, ts.reward, ts.discount, ts.observation["position_error"]   # (64,), (64,), (64,), (64, 2)

Each episode is the task's own (:class:`usv_mj.envs.tasks.TrackTask`: the scenario, the reference, the
control step with its quantizers and actuators, the observation, the reward and the termination),
with its own start pose (drawn from its own ``RandomState``, as the task draws it), its own
control-step state and its own plant state; one call of the generated ``step_batch`` advances all of
them: per episode the action, the control step and the plant's step (the one generator's
``advance``, :mod:`usv_mj.loop.generate`), the observation vector, the reward and the termination's
code, in a ``numba.prange`` over the episodes. The kernels are the single environment's
(:mod:`usv_mj.envs.native`), so an episode's observations, rewards and ends equal those of a single
environment (``usv_mj.envs.load``) given the same seed and actions, bit for bit
(tests/test_vector_env.py); only episodes that end go through Python (their reason, their reset).

``plant``: "mujoco" (the tasks' plant: one MuJoCo model and data per episode, ``mj_step`` called by
address from the threads, the hydrodynamics a C callback: no GIL) or "analytic" (RK4 of Eqs. 1-2 in
native code: the fast one, for learning at scale).

The argument arrays are held as :mod:`usv_mj.loop.batch` holds a batched run's (state per episode,
equal parameters once). What is not batched: the harbour tasks (a new MuJoCo model per layout, moving
obstacles in Python, contacts): :func:`usv_mj.envs.gymnasium_vector.make_vector_env` steps those one by one.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from usv_mj.builder import make_actuators, make_plant, make_quantizers
from usv_mj.loop.batch import episode_tuple, stack, threads, write_back
from usv_mj.loop.generate import generate
from usv_mj.loop.simulate import which_limit
from usv_mj.loop.step import C_F_U, C_Q_U, C_S_U, C_TAU_U, ControlStep
from usv_mj.record.run_record import N_CORE

from usv_mj.envs import native
from usv_mj.envs.environment import load
from usv_mj.envs.tasks import (_GAUSS_SCALE, _EXP, TRACK_REWARD_HEADING_RAD, TRACK_REWARD_POSITION_M, HarbourTask,
                               track_start_pose)

#: the termination codes step_batch writes (0: the episode goes on)
RUNNING, FAILED, DIVERGED, LOST = 0, 1, 2, 3
KINDS = {FAILED: "diverged", DIVERGED: "diverged", LOST: "lost"}

_BODY = '''
    for i in {loop}(X.shape[0]):
        if not ACTIVE[i]:
            continue
        a0 = np.float64(A[i, 0])
        a1 = np.float64(A[i, 1])
        if normalized:   # the Gymnasium view's action (USVGymEnv.physical_action): [-1, 1] -> [low, high]
            a0 = min(max(a0, -1.0), 1.0)
            a1 = min(max(a1, -1.0), 1.0)
            a0 = a0 * HIGH[0] if a0 >= 0.0 else -a0 * LOW[0]
            a1 = a1 * HIGH[1] if a1 >= 0.0 else -a1 * LOW[1]
        k = K[i]
        t = t0 + (k + 1) * dt   # the plant's time after the step (time_at(k + 1))
        x, failed, refs, out, ex, ey, e_psi, diverged, gx, gy = step_track(
            a0, a1, ROW[i], {step_ep}, k, X[i], t, {plant_ep}, preview, params, n_out, {ref_ep})
        K[i] = k + 1
        for j in range(6):
            X[i, j] = x[j]
        for j in range(n_out):
            OBS[i, j] = out[j]
        if scaled:
            observe_scaled(out, OSCALE, OLO, OHI, OBS32[i])
        REW[i] = track_reward(ex, ey, e_psi, rp)
        code = {RUNNING}
        if failed:
            code = {FAILED}
        elif diverged:
            code = {DIVERGED}
        elif hypot_py(ex, ey) >= rp[{R_MAX_DISTANCE}]:
            code = {LOST}
        CODE[i] = code
'''

_SIGNATURE = ('(A, normalized, LOW, HIGH, ACTIVE, K, X, t0, dt, ROW, preview, params, n_out, OBS, REW, CODE, rp, '
              'scaled, OSCALE, OLO, OHI, OBS32, step_a, plant_a, ref_a):')

_TEMPLATE = f'''

@njit(cache=True, parallel=True)
def step_batch{_SIGNATURE}
    """One control period of every ACTIVE episode (usv_mj.envs.batch)."""
{_BODY.replace("{loop}", "prange")}

@njit(cache=True)
def step_serial{_SIGNATURE}
    """step_batch on the calling thread (few episodes: no fork and join)."""
{_BODY.replace("{loop}", "range")}

@njit(cache=True)
def observe(IDX, X, t, preview, params, n_out, OBS, scaled, OSCALE, OLO, OHI, OBS32, ref_a):
    """The observation vector of the episodes IDX at their state X[i] and time t (a reset's)."""
    for m in range(IDX.shape[0]):
        i = IDX[m]
        refs, out, ex, ey, e_psi, diverged, gx, gy = evaluate(X[i], t, preview, params, n_out, False, {{ref_ep}})
        for j in range(n_out):
            OBS[i, j] = out[j]
        if scaled:
            observe_scaled(out, OSCALE, OLO, OHI, OBS32[i])
'''

_IMPORTS = ("from numba import prange\n"
            "from usv_mj.envs.native import harbor_sense, hypot_py, observe_scaled, track_observe, track_reward")


class NotBatched(ValueError):
    """The task cannot be stepped by :class:`TrackBatch` (its obstacles move in Python, its reference
    changes during the episode): the vector view steps it env by env."""


class BatchTimeStep(NamedTuple):
    """A dm_env ``TimeStep`` of every episode: ``step_type`` (N,) of dm_env.StepType values, ``reward``
    and ``discount`` (N,) (NaN where an episode starts: dm_env's None), ``observation`` an
    OrderedDict of (N, ...) arrays (the task's, in its order; ``flat``: one ``observations`` (N, n))."""

    step_type: np.ndarray
    reward: np.ndarray
    discount: np.ndarray
    observation: object


class TrackBatch:
    """``num_envs`` episodes of a track task (module docstring), each seeded ``seed + i`` (None: fresh
    entropy). ``single``: a :func:`usv_mj.envs.load` environment of the task to take its definition
    from (default: one is made with ``options``). ``scaled``: also keep the Gymnasium view's float32
    observation (``scale``, ``lo``, ``hi``: per entry of the vector; usv_mj.envs.gymnasium_vector).
    ``n_threads``: numba threads for the steps (None: numba's setting); ``parallel``: step on
    threads (None: when there are enough episodes to pay for it)."""

    def __init__(self, task: str = "track", num_envs: int = 1, seed=None, *, plant: str = "mujoco", single=None,
                 n_threads: int | None = None, parallel: bool | None = None, scaled=None, **options):
        if not (isinstance(num_envs, (int, np.integer)) and num_envs >= 1):
            raise ValueError(f"usv_mj.envs.load_batch: num_envs must be an integer >= 1, got {num_envs!r}")
        if plant not in ("mujoco", "analytic"):
            raise ValueError(f"usv_mj.envs.load_batch: plant must be 'mujoco' or 'analytic', got {plant!r}")
        self.single = single if single is not None else load(task, **options)
        t = self.single.task
        if isinstance(t, HarbourTask) or not getattr(t, "_fusable", False):
            raise NotBatched(f"usv_mj.envs.load_batch: the task {task!r} is not batched natively (its obstacles "
                             f"move in Python); gymnasium.make_vec steps it env by env (SyncVectorEnv)")
        if _EXP is not math.exp:   # numpy's exp is not libm's here: the single env's rewards use numpy's
            import warnings

            warnings.warn("usv_mj.envs.load_batch: numpy's exp is not libm's on this CPU; the batch's rewards "
                          "may differ from the single environment's in the last bit", RuntimeWarning, stacklevel=2)
        self.task_name, self.task, self.plant_kind = task, t, plant
        n = self.num_envs = int(num_envs)
        sc = t.scenario
        self.scenario = sc
        self.dt = sc.control_period
        self.step_limit = self.single._step_limit
        self.time_limit = t.time_limit
        self.n_obs = t._n_obs
        self.params = t._params.copy()
        self.preview = np.ascontiguousarray(t.preview_times, dtype=np.float64)
        evaluator = native.StepEvaluator(t.reference, t.preview_times)
        if not evaluator.native or evaluator.key_fn is not None:
            raise NotBatched(f"usv_mj.envs.load_batch: the task's reference ({type(t.reference).__name__}) has no "
                             f"fixed kernel")
        if evaluator.t_max is not None and evaluator.t_max < self.time_limit + evaluator.horizon:
            raise ValueError("usv_mj.envs.load_batch: the reference's table ends before the episode's preview does")
        self.reference = t.reference
        self.rp = np.zeros(native.N_REWARD)
        self.rp[native.R_TWO] = 2.0
        self.rp[native.R_GAUSS_SCALE] = _GAUSS_SCALE
        self.rp[native.R_POSITION] = TRACK_REWARD_POSITION_M
        self.rp[native.R_HEADING] = TRACK_REWARD_HEADING_RAD
        self.rp[native.R_MAX_DISTANCE] = t.max_distance
        self.low, self.high = np.asarray(t.action_low, float).copy(), np.asarray(t.action_high, float).copy()
        # each episode's control step, made as the task makes its own (the action bounds, Eq. 3, the actuators)
        self.controls = []
        for _ in range(n):
            c = ControlStep(make_quantizers(sc), make_actuators(sc), t._bounds_t)
            c.quantize = t.quantize
            self.controls.append(c)
        self._step = stack([c.kernel() for c in self.controls])
        self._ref = stack([self.reference.kernel()] * n)
        # the plants: one analytic plant's kernel for all (its arguments are parameters), or a MuJoCo
        # model and data per episode (their addresses stacked); their sea generated for the whole episode
        t_end = self.time_limit + 2.0 * self.dt
        if plant == "analytic":
            self.plants = [make_plant(sc, "analytic")]
            self.plants[0].reset(np.zeros(3), np.zeros(3), 0.0)
            pks = [self.plants[0].kernel(t_end)] * n
        else:
            self.plants = [make_plant(sc, "mujoco") for _ in range(n)]
            pks = [p.kernel(t_end) for p in self.plants]
        self._pks = pks
        self._plant = stack(pks)
        self.t0 = 0.0
        # the batch's own storage
        self.X = np.zeros((n, 6))
        self.K = np.zeros(n, np.int64)
        self.ROW = np.zeros((n, N_CORE))
        self.OBS = np.zeros((n, self.n_obs))
        self.REW = np.zeros(n)
        self.CODE = np.zeros(n, np.int64)
        self._all = np.ones(n, np.bool_)
        self.last_action = self.ROW[:, C_TAU_U:C_TAU_U + 2]     # (N, 2) views, as the task's last_* of one episode
        self.last_command = self.ROW[:, C_Q_U:C_Q_U + 2]
        self.last_thrust = self.ROW[:, C_F_U:C_F_U + 2]
        self.last_saturated = self.ROW[:, C_S_U:C_S_U + 2]
        self.scaled = scaled is not None
        if self.scaled:
            scale, lo, hi = (np.ascontiguousarray(v, dtype=np.float64) for v in scaled)
            self.OSCALE, self.OLO, self.OHI = scale, lo, hi
        else:
            self.OSCALE = self.OLO = self.OHI = np.zeros(self.n_obs)
        self.OBS32 = np.zeros((n, self.n_obs), np.float32)
        self.rngs = [np.random.RandomState(None if seed is None else int(seed) + i) for i in range(n)]
        self.n_threads = n_threads
        self.parallel = (n >= (2 if plant == "mujoco" else 32)) if parallel is None else bool(parallel)
        masks = {"step": self._step.mask, "plant": self._plant.mask, "ref": self._ref.mask}
        self._module = generate("usv_mj_envbatch", native._TEMPLATE + _TEMPLATE,
                                {"ref": (self.reference.kernel().fn, len(self._ref.args)),
                                 "plant": (pks[0].fn, len(self._plant.args))}, imports=_IMPORTS,
                                step_ep=episode_tuple("step", masks["step"]),
                                plant_ep=episode_tuple("plant", masks["plant"]),
                                ref_ep=episode_tuple("ref", masks["ref"]),
                                RUNNING=RUNNING, FAILED=FAILED, DIVERGED=DIVERGED, LOST=LOST,
                                R_MAX_DISTANCE=native.R_MAX_DISTANCE)
        self._closed = False

    # --- episodes ---------------------------------------------------------------------------------------------

    def seed(self, seed) -> None:
        """Episode i's random state: ``RandomState(seed + i)`` (None: fresh entropy for each)."""
        self.rngs = [np.random.RandomState(None if seed is None else int(seed) + i) for i in range(self.num_envs)]

    def reset_envs(self, idx) -> None:
        """Start a new episode in each of ``idx`` (as the task's initialize_episode: the control step at
        rest, the row cleared, a start pose drawn from its random state, the plant there at t = 0)
        and observe it (into :attr:`OBS`, and :attr:`OBS32` when scaled)."""
        idx = np.asarray(idx, dtype=np.int64).reshape(-1)
        if idx.size == 0:
            return
        t = self.task
        for i in idx.tolist():
            c = self.controls[i]
            c.reset()
            for j, vals in self._step.back:   # the reset state into the batch's rows
                self._step.args[j][i] = vals[i]
            self.ROW[i] = 0.0
            eta0, nu0 = track_start_pose(self.reference, self.rngs[i], t.start_offset)
            if self.plant_kind == "analytic":
                self.X[i, :3] = eta0
                self.X[i, 3:] = nu0
            else:
                import mujoco

                p = self.plants[i]
                p.reset(eta0, nu0, 0.0)
                mujoco.mj_forward(p.model, p.data)   # dm_control's after_reset, as the single environment
                self.X[i] = p.state
            self.K[i] = 0
            self.CODE[i] = RUNNING
        self._module.observe(idx, self.X, self.t0, self.preview, self.params, self.n_obs, self.OBS, self.scaled,
                             self.OSCALE, self.OLO, self.OHI, self.OBS32, self._ref.args)

    def advance(self, actions, normalized: bool = False, active=None) -> None:
        """One control period of the episodes ``active`` (a bool mask; None: all) under ``actions``
        ((N, 2): the thrust [N, N m], or ``normalized`` in [-1, 1] as the Gymnasium view's). Fills
        :attr:`OBS`, :attr:`REW`, :attr:`CODE` and the state; raises ValueError for a non-finite action."""
        if self._closed:
            raise RuntimeError("usv_mj.envs.load_batch: the batch is closed")
        a = np.asarray(actions)
        if a.shape != (self.num_envs, 2):
            raise ValueError(f"usv_mj.envs batch: actions must have shape ({self.num_envs}, 2), got {a.shape}")
        if a.dtype not in (np.float32, np.float64):
            a = a.astype(np.float64)
        act = self._all if active is None else np.ascontiguousarray(active, dtype=np.bool_)
        if not np.isfinite(a[act]).all():
            bad = int(np.flatnonzero(act & ~np.isfinite(a).all(axis=1))[0])
            raise ValueError(f"usv_mj.envs batch: the action of env {bad} must be finite, got {a[bad].tolist()}")
        fn = self._module.step_batch if self.parallel else self._module.step_serial
        with threads(self.n_threads):
            fn(a, bool(normalized), self.low, self.high, act, self.K, self.X, self.t0, self.dt, self.ROW, self.preview,
               self.params, self.n_obs, self.OBS, self.REW, self.CODE, self.rp, self.scaled, self.OSCALE, self.OLO,
               self.OHI, self.OBS32, self._step.args, self._plant.args, self._ref.args)

    def ends(self):
        """(terminated, truncated) of the last :meth:`advance`, as the single environment decides them:
        the time limit wins (discount 1) even over a termination at that same step."""
        truncated = self.K >= self.step_limit
        return (self.CODE != RUNNING) & ~truncated, truncated

    def end_info(self, i: int, truncated: bool) -> tuple[str, str]:
        """(kind, reason) of episode ``i``'s end (as the task's ``info``; made only for episodes that end)."""
        t = self.t0 + int(self.K[i]) * self.dt
        code = int(self.CODE[i])
        if code == FAILED:
            kind, reason = "diverged", self._failure(i)
        elif code == DIVERGED:
            x = self.X[i]
            ref = self.reference.evaluate(t)
            kind = "diverged"
            reason = (f"state left its limits at t = {t:.3f} s: "
                      f"{which_limit(x, x[0] - ref[0], x[1] - ref[1], self.scenario.limits)}")
        elif code == LOST:
            x = self.X[i]
            ref = self.reference.evaluate(t)
            dist = math.hypot(x[0] - ref[0], x[1] - ref[1])
            kind = "lost"
            reason = (f"distance to the reference {dist:.3g} m reached max_distance = {self.task.max_distance:g} m "
                      f"at t = {t:.3f} s")
        elif truncated:
            kind, reason = "time_limit", f"reached the time limit at t = {t:.3f} s"
        else:
            return None, None
        return kind, f"{kind}: {reason}"

    def _failure(self, i: int) -> str:
        pk = self._pks[i]
        try:
            if pk.fail is not None:
                pk.fail(int(self.K[i]) - 1)
        except Exception as exc:   # the plant's own error, as the single environment keeps it
            return str(exc)
        return "the plant's step failed"

    def write_back(self, i: int) -> None:
        """Episode ``i``'s control-step state into its :class:`ControlStep` (its quantizers' levels and
        switch counts, its actuators' state), e.g. to read ``controls[i].switches``."""
        write_back(self._step, i)

    def observation(self, rows=None) -> dict:
        """The observation dict of :attr:`OBS` (views; ``rows``: a subset)."""
        return _dict_of(self.task, self.OBS if rows is None else self.OBS[rows])

    # --- the dm_env view ------------------------------------------------------------------------------------

    def reset(self) -> BatchTimeStep:
        """Every episode starts (dm_env's FIRST: reward and discount NaN)."""
        self.reset_envs(np.arange(self.num_envs))
        self._last = np.zeros(self.num_envs, np.bool_)
        n = self.num_envs
        return BatchTimeStep(np.zeros(n, np.int8), np.full(n, np.nan), np.full(n, np.nan), self._obs())

    def step(self, actions) -> BatchTimeStep:
        """One control period (dm_env's rule: an episode whose last step ended it starts again here,
        FIRST, its action unused) under the thrust ``actions`` (N, 2) [N, N m]."""
        if not hasattr(self, "_last"):
            return self.reset()
        again = self._last
        active = ~again
        self.advance(actions, False, active)
        terminated, truncated = self.ends()
        n = self.num_envs
        step_type = np.where(terminated | truncated, np.int8(2), np.int8(1)).astype(np.int8)
        reward = self.REW.copy()
        discount = np.where(terminated, 0.0, 1.0)
        idx = np.flatnonzero(again)
        if idx.size:
            self.reset_envs(idx)
            step_type[idx] = 0
            reward[idx] = np.nan
            discount[idx] = np.nan
        self._last = (step_type == 2)
        return BatchTimeStep(step_type, reward, discount, self._obs())

    def _obs(self):
        import collections

        if self.single.flat_observation:
            return collections.OrderedDict(observations=self.OBS.copy())
        return _dict_of(self.task, self.OBS.copy())

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            for p in self.plants:
                p.close()
            self.single.close()


def _dict_of(task, v):
    """The task's observation dict of a (N, n) batch of vectors (views of it)."""
    import collections

    out = collections.OrderedDict()
    for name, part, shape, _ in task.observation_views():
        out[name] = v[:, part].reshape((v.shape[0],) + tuple(shape))
    return out


def load_batch(task: str = "track", num_envs: int = 1, seed=None, *, plant: str = "mujoco",
               n_threads: int | None = None, **options) -> TrackBatch:
    """``num_envs`` episodes of ``task`` stepped in one native call (:class:`TrackBatch`: the dm_env
    users' batch; ``reset()`` and ``step(thrust)`` give a :class:`BatchTimeStep` of arrays). Options
    as :func:`usv_mj.envs.load`'s; ``plant``: "mujoco" (the tasks' own) or "analytic"."""
    return TrackBatch(task, num_envs, seed, plant=plant, n_threads=n_threads, **options)
