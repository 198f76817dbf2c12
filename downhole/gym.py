"""The drilling plant as a Gymnasium environment (``downhole/Drilling-v0``) for RL users.

>>> import gymnasium as gym, downhole.gym                         # doctest: +SKIP
>>> env = gym.make("downhole/Drilling-v0", model="lumped")        # doctest: +SKIP
>>> env = downhole.gym.DrillingEnv.from_scenario("examples/sil_pi_hybrid68.toml")  # doctest: +SKIP

Each ``step`` holds the action for ``control_dt`` s (``control_dt / dt`` plant steps).

Action (``Box(-1, 1, (2,))``), mapped linearly from [-1, 1] to [0, max]:

- ``a[0]``: axial command: weight on bit 0..``wob_max`` N (hook load = string weight - WOB) for
  the directional plants, or top-drive axial velocity 0..``v_max`` m/s for the lumped one;
- ``a[1]``: top-drive speed set-point 0..``omega_max`` rad/s.

Observation (``Box(-inf, inf, (7,), float32)``), scaled: bit axial velocity / v_s, bit angular
velocity / w_s, WOB / 1e5 N, TOB / 1e4 N m, top-drive angular velocity / w_s, reference axial
velocity / v_s, reference angular velocity / w_s, with v_s = 0.01 m/s and w_s = 20 rad/s.

Reward of one step (the mean over its plant steps j)::

    r = - mean_j[ ((v_j - v_ref) / v_s)^2 + ((omega_j - omega_ref) / w_s)^2 ]
        - stuck_weight * mean_j[ |omega_j| < 0.1 rad/s ]       (stick phase)
        - bounce_weight * mean_j[ WOB_j <= 0 ]                 (bit off bottom)

(stuck_weight = bounce_weight = 1 by default), so perfect tracking without stick-slip or bit
bounce scores 0. The episode is truncated after ``episode_seconds``; it terminates (reward
-100) if the simulation diverges. The reference is drawn at reset from ``reference_range`` (or
fixed by ``reference``); ``info`` carries the unscaled signals. ``reset(options={"start":
"steady", "set_point": {...}})`` starts from a mode of the Plant contract (default: rest).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from downhole.errors import DownholeInputError, SimulationDiverged

__all__ = ["ENV_ID", "DrillingEnv"]

ENV_ID = "downhole/Drilling-v0"
V_S, W_S = 0.01, 20.0


class DrillingEnv(gym.Env):
    """Drilling plant environment (see the module docstring for spaces and reward).

    Parameters
    ----------
    model : str
        ``"lumped"`` (fast, default) or a directional plant (``"hybrid24"``, ``"hybrid68"``...).
    dt : float
        Plant step, s.
    control_dt : float
        Action hold time, s (multiple of ``dt``).
    episode_seconds : float
        Truncation time, s.
    reference : (float, float), optional
        Fixed (v_ref m/s, omega_ref rad/s); default: drawn from ``reference_range``.
    reference_range : ((float, float), (float, float))
        Uniform ranges of v_ref and omega_ref.
    wob_max, v_max, omega_max : float
        Action ranges (N, m/s, rad/s).
    stuck_weight, bounce_weight : float
        Reward penalty weights.
    plant : SilPlant, optional
        A plant already built (``model`` is then ignored); :meth:`from_scenario` builds it
        from a scenario file.
    """

    metadata = {"render_modes": []}

    def __init__(self, model: str = "lumped", dt: float = 1e-3, control_dt: float = 0.05,
                 episode_seconds: float = 20.0, reference=None,
                 reference_range=((0.005, 0.02), (10.0, 30.0)), wob_max: float = 250e3,
                 v_max: float = 0.03, omega_max: float = 40.0, stuck_weight: float = 1.0,
                 bounce_weight: float = 1.0, plant=None):
        from downhole.sil.plants import build_plant

        n = int(round(control_dt / dt))
        if n < 1 or abs(n * dt - control_dt) > 1e-9:
            raise DownholeInputError(f"control_dt = {control_dt} s must be a multiple of "
                                     f"dt = {dt} s")
        if episode_seconds <= 0:
            raise DownholeInputError(f"episode_seconds must be > 0, got {episode_seconds}")
        if plant is not None and abs(plant.dt - dt) > 1e-12:
            raise DownholeInputError(f"the plant steps at dt = {plant.dt:g} s, not {dt:g} s")
        self.plant = plant if plant is not None else build_plant(model, interface="surface",
                                                                 dt=dt)
        self.substeps = n
        self.control_dt = n * dt
        self.max_steps = int(round(episode_seconds / self.control_dt))
        self.fixed_reference = None if reference is None else tuple(map(float, reference))
        self.reference_range = reference_range
        self.wob_max, self.v_max, self.omega_max = float(wob_max), float(v_max), float(omega_max)
        self.stuck_weight, self.bounce_weight = float(stuck_weight), float(bounce_weight)
        self.weight = self.plant.safe_command().get("hook_load", 0.0)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(7,), dtype=np.float32)
        self._ref = (0.01, 20.0)
        self._k = 0
        self._obs = None

    @classmethod
    def from_scenario(cls, path, **overrides) -> DrillingEnv:
        """The environment of a scenario file, read with the schema every command uses
        (:func:`downhole.sil.scenario.load_sil_scenario`): the plant of ``[model]``, ``[bit]``,
        ``[operation]`` and ``[simulation]`` (``dt``, ``depth_of_cut``; ``duration`` is the
        episode length), the fixed reference of ``[reference]``. ``overrides`` are the
        constructor's other keywords (``control_dt``, ``wob_max``, ...).

        Raises
        ------
        ScenarioError
            A bad file (one line naming the file and the dotted field).
            A plant with the ``state`` interface (the environment drives the surface), a HIL
            plant (``[link] mode = "hil"``: its bit velocities come from a rig on the link).
        """
        from downhole.errors import ScenarioError
        from downhole.sil.scenario import build_from_scenario, load_sil_scenario

        sc = load_sil_scenario(path)
        if sc.model.interface != "surface":
            raise ScenarioError(str(path), "model.interface", f"{sc.model.interface!r}: the "
                                "environment drives the surface (interface = 'surface')")
        if sc.link.mode == "hil":
            raise ScenarioError(str(path), "link.mode", "'hil': the HIL plant takes its bit "
                                "velocities from a rig over the link; the environment has no "
                                "link (remove [link] mode to train on the plant alone)")
        plant, _ = build_from_scenario(sc, with_controller=False)
        kw = dict(dt=sc.simulation.dt, episode_seconds=sc.simulation.duration,
                  reference=(sc.reference.axial_velocity, sc.reference.angular_velocity))
        kw.update(overrides)
        return cls(plant=plant, **kw)

    def command(self, action) -> dict:
        """The plant command for an action (the documented linear maps)."""
        a = np.clip(np.asarray(action, dtype=float), -1.0, 1.0)
        frac = (a + 1.0) / 2.0
        ax, tq = self.plant.command_names
        if ax == "hook_load":
            first = self.weight - frac[0] * self.wob_max
        else:
            first = frac[0] * self.v_max
        return {ax: float(first), tq: float(frac[1] * self.omega_max)}

    def _observe(self, o) -> np.ndarray:
        v_ref, w_ref = self._ref
        return np.array([o["bit_axial_velocity"] / V_S, o["bit_angular_velocity"] / W_S,
                         o["wob"] / 1e5, o["tob"] / 1e4, o["top_drive_angular_velocity"] / W_S,
                         v_ref / V_S, w_ref / W_S], dtype=np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if self.fixed_reference is not None:
            self._ref = self.fixed_reference
        else:
            (v0, v1), (w0, w1) = self.reference_range
            self._ref = (float(self.np_random.uniform(v0, v1)),
                         float(self.np_random.uniform(w0, w1)))
        start = {k: v for k, v in (options or {}).items() if k in ("start", "set_point",
                                                                  "clearance")}
        self._obs = self.plant.reset(**start)  # the Plant contract's start modes
        self._k = 0
        return self._observe(self._obs), {"reference": self._ref}

    def step(self, action):
        cmd = self.command(action)
        v_ref, w_ref = self._ref
        err = stuck = bounce = 0.0
        o = self._obs
        try:
            for _ in range(self.substeps):
                o = self.plant.step(cmd)
                err += ((o["bit_axial_velocity"] - v_ref) / V_S) ** 2 + \
                    ((o["bit_angular_velocity"] - w_ref) / W_S) ** 2
                stuck += abs(o["bit_angular_velocity"]) < 0.1
                bounce += o["wob"] <= 0.0
        except SimulationDiverged:
            return self._observe(self._obs), -100.0, True, False, {"diverged": True}
        n = self.substeps
        reward = -(err / n) - self.stuck_weight * stuck / n - self.bounce_weight * bounce / n
        self._obs = o
        self._k += 1
        info = {"reference": self._ref, "command": cmd, "tracking_error": err / n,
                "stuck_fraction": stuck / n, "bounce_fraction": bounce / n,
                "signals": {k: o[k] for k in ("bit_axial_velocity", "bit_angular_velocity",
                                              "wob", "tob")}}
        return self._observe(o), float(reward), False, self._k >= self.max_steps, info


if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="downhole.gym:DrillingEnv")
