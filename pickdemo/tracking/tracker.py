"""The target tracker: fuses perception's estimates into one belief of the target's pose and rates.

Pure: estimates in, a Gaussian belief out. A constant-velocity Kalman filter on the state
``(x, y, z, yaw, vx, vy, vz, vyaw)`` (m, rad, m/s, rad/s), white-noise acceleration as process noise.

- **Measurement noise** is the estimate's own covariance (position and yaw), plus a floor for what
  the method's model of itself leaves out (an arm passing in front, rasterised edges).
- **Latency**: an estimate refers to the time its frame was taken. The filter's state is kept at the
  time of the newest estimate it has taken in; :meth:`TargetTracker.predict` carries it to any later
  time (the controller asks for *now*), so the delay is compensated with the estimated rates.
- **Outliers** are rejected with a Mahalanobis gate on the innovation. A run of rejected estimates
  that agree with each other is not an outlier but a world that changed (the target was pushed, or
  its belt changed speed): when :attr:`TrackerParams.jump_confirm` of them in a row fit one
  constant-velocity motion (a weighted line fit with the track's prior on the rates, tested by its
  chi-square), the filter restarts from that fit, position and rates, and counts a jump, which the
  controller reads.
- **Yaw** is known modulo the target's symmetry (a quarter turn for a square box, a half turn for
  any box); innovations are wrapped to that period. A cylinder has no yaw: its yaw is not updated.
- **Lost**: no estimate accepted for :attr:`TrackerParams.lost_after_s`; the controller decides what
  that means where it is (while the hand hides the target on purpose, nothing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickdemo.core.geometry import wrap_angle
from pickdemo.perception import PoseEstimate

#: 99.9 % quantiles of the chi-square distribution, by degrees of freedom (the gate's threshold).
CHI2_999 = {3: 16.266, 4: 18.467, 6: 22.458, 8: 26.124, 9: 27.877, 12: 32.909}


@dataclass(frozen=True)
class TrackerParams:
    """Noise and gating; SI units."""

    accel_sigma_m_s2: float = 0.01  # white-noise acceleration (m/s^2): a real move beyond it is a jump
    vertical_accel_sigma_m_s2: float = 1e-4  # it rests on a table or a belt: its height hardly moves
    yaw_accel_sigma_rad_s2: float = 0.05
    position_floor_m: float = 0.0007  # added to each estimate's standard deviation, per axis
    yaw_floor_rad: float = float(np.radians(0.7))
    initial_speed_sigma_m_s: float = 0.05  # prior on the horizontal rates when a track starts
    initial_vertical_speed_sigma_m_s: float = 1e-3
    initial_yaw_rate_sigma_rad_s: float = 0.2
    jump_confirm: int = 3  # rejected estimates in a row that agree with each other: the target moved
    partial_floor_factor: float = 5.0  # a partial view's floor is this many times the usual
    lost_after_s: float = 1.0

    def __post_init__(self) -> None:
        if min(self.accel_sigma_m_s2, self.position_floor_m, self.yaw_floor_rad, self.lost_after_s) <= 0.0:
            raise ValueError("tracker noise levels and lost_after_s must be positive")
        if self.jump_confirm < 2:
            raise ValueError("jump_confirm must be at least 2")


@dataclass(frozen=True)
class TrackedPose:
    """The belief at one time: mean and covariance of (x, y, z, yaw) and of their rates."""

    time_s: float
    position: np.ndarray  # (3,) m
    yaw_rad: float
    velocity: np.ndarray  # (3,) m/s
    yaw_rate_rad_s: float
    covariance: np.ndarray  # (8, 8): what the estimates' own noise leaves uncertain
    #: the cameras' calibration that the position carries (m, per axis): a bias no number of frames of
    #: one camera averages away (0: their poses exact)
    calibration_sigma_m: float = 0.0

    @property
    def position_sigma_m(self) -> float:
        """The largest standard deviation of the position (m), from the estimates' noise."""
        return float(np.sqrt(np.max(np.linalg.eigvalsh(self.covariance[:3, :3]))))

    @property
    def grasp_sigma_m(self) -> float:
        """The largest standard deviation of where the target is (m): noise and calibration both."""
        return float(np.hypot(self.position_sigma_m, self.calibration_sigma_m))


@dataclass(frozen=True)
class TrackerUpdate:
    """What became of one estimate."""

    accepted: bool
    mahalanobis2: float  # squared Mahalanobis distance of the innovation
    jumped: bool = False  # the track restarted here: the target moved
    reason: str = ""


class TargetTracker:
    """Kalman filter over the target's pose and rates, with a gate and jump detection."""

    def __init__(self, yaw_symmetry_rad: float, params: TrackerParams | None = None) -> None:
        """``yaw_symmetry_rad``: the model looks the same after this turn (0 for a cylinder: no yaw)."""
        self.params = params or TrackerParams()
        self.symmetry = yaw_symmetry_rad
        self.has_yaw = yaw_symmetry_rad > 0.0
        self._x: np.ndarray | None = None
        self._P = np.zeros((8, 8))
        self._t = 0.0
        self._last_accept_s: float | None = None
        #: the run of rejected estimates (t, z, R, with yaw) of each camera: one camera's outliers do not
        #: break another's run
        self._runs: dict[str, list[tuple[float, np.ndarray, np.ndarray, bool]]] = {}
        #: each camera's calibration variance (m^2 per axis), and the share of its bias in the track's position
        self._calibration: dict[str, float] = {}
        self._share: dict[str, float] = {}
        self.accepted = 0
        self.rejected = 0
        self.jumps = 0

    # ----------------------------------------------------------------------------------- queries
    @property
    def initialised(self) -> bool:
        return self._x is not None

    def share_of(self, source: str) -> float:
        """The share of a camera's estimates in the track (0: none of it is that camera's)."""
        return self._share.get(source, 0.0)

    @property
    def last_accept_s(self) -> float | None:
        """Frame time of the newest accepted estimate."""
        return self._last_accept_s

    def lost(self, now_s: float) -> bool:
        """No estimate accepted for ``lost_after_s`` (or none ever)."""
        return self._last_accept_s is None or now_s - self._last_accept_s > self.params.lost_after_s

    def predict(self, time_s: float) -> TrackedPose:
        """The belief carried forward to ``time_s`` (never before the newest estimate taken in)."""
        if self._x is None:
            raise RuntimeError("the tracker has no estimate yet")
        x, P = self._propagate(max(time_s - self._t, 0.0))
        return TrackedPose(
            time_s=max(time_s, self._t),
            position=x[:3].copy(),
            yaw_rad=float(x[3]),
            velocity=x[4:7].copy(),
            yaw_rate_rad_s=float(x[7]),
            covariance=P,
            calibration_sigma_m=float(np.sqrt(self._track_bias())),
        )

    # ---------------------------------------------------------------------------------- updates
    def update(
        self, estimate: PoseEstimate, time_s: float, *, partial: bool = False, source: str = "camera"
    ) -> TrackerUpdate:
        """Take in an estimate from a frame taken at ``time_s`` (estimates must come in time order).

        ``partial``: the estimate saw only part of the target (the hand over it); it is trusted less
        (its noise floor times ``partial_floor_factor``), and if rejected it never counts towards a
        restart (a partly hidden face can mislead the fit consistently): the filter predicts through.
        ``source``: the camera that took it; a restart needs a run of one camera's estimates.
        """
        z, R = self._measurement(estimate, floor_factor=self.params.partial_floor_factor if partial else 1.0)
        cal = estimate.calibration_cov
        self._calibration[source] = 0.0 if cal is None else float(np.trace(cal)) / 3.0
        with_yaw = self.has_yaw and bool(np.isfinite(R[3, 3]))  # an estimator may measure no orientation
        if not with_yaw:
            R[3, 3] = 0.0
        if self._x is None:
            self._start(z, R, time_s, with_yaw)
            self._share = {source: 1.0}
            return TrackerUpdate(True, 0.0)
        if time_s < self._t:
            return TrackerUpdate(False, float("nan"), reason="older than the track")
        x, P = self._propagate(time_s - self._t)
        H = self._H(with_yaw)
        innov = H @ z - H @ x
        if with_yaw:
            innov[3] = wrap_angle(innov[3], self.symmetry)
        S = H @ P @ H.T + H @ R @ H.T
        # Calibration: this camera's bias and the track's (its cameras' biases, by their shares) differ
        # by this much (0 for the one camera that made the track); the track's own bias, less what it
        # shares with this camera, is what this estimate can correct.
        s_e, w_e, b_track = self._calibration[source], self._share.get(source, 0.0), self._track_bias()
        differ = s_e - 2.0 * w_e * s_e + b_track
        correctable = max(b_track - w_e * s_e, 0.0)
        if differ > 0.0:
            S[:3, :3] += np.eye(3) * differ
        d2 = float(innov @ np.linalg.solve(S, innov))
        if d2 > CHI2_999[len(innov)]:
            self.rejected += 1
            run = self._runs.setdefault(source, [])
            if partial:
                run.clear()
                return TrackerUpdate(False, d2, reason=f"beyond the gate ({np.sqrt(d2):.1f} sigma), a partial view")
            run.append((time_s, z, R, with_yaw))
            fit = self._jump_fit(run)
            if fit is not None:
                self._restart(*fit, time_s)
                self._share = {source: 1.0}
                self.jumps += 1
                return TrackerUpdate(True, d2, jumped=True, reason="the target moved: the track restarts")
            return TrackerUpdate(False, d2, reason=f"Mahalanobis distance {np.sqrt(d2):.1f} beyond the gate")
        PH = P @ H.T
        if correctable > 0.0:
            PH[:3, :3] += np.eye(3) * correctable
        K = PH @ np.linalg.inv(S)
        x = x + K @ innov
        I_KH = np.eye(8) - K @ H
        P = I_KH @ P @ I_KH.T + K @ (H @ R @ H.T) @ K.T  # Joseph form: stays symmetric and positive
        self._x, self._P, self._t = x, 0.5 * (P + P.T), time_s
        k = float(np.trace(K[:3, :3])) / 3.0  # the position's gain: this camera's share of the track now
        if any(self._calibration.values()):
            self._share = {c: (1.0 - k) * w for c, w in self._share.items()}
            self._share[source] = self._share.get(source, 0.0) + k
        self._last_accept_s = time_s
        self._runs.clear()
        self.accepted += 1
        return TrackerUpdate(True, d2)

    # --------------------------------------------------------------------------------- internals
    def _track_bias(self) -> float:
        """The calibration variance the track's position carries (m^2 per axis)."""
        return sum(w * w * self._calibration.get(c, 0.0) for c, w in self._share.items())

    def _H(self, with_yaw: bool | None = None) -> np.ndarray:
        """Rows of the state that a measurement observes: position, and yaw where there is one."""
        rows = [0, 1, 2, 3] if (self.has_yaw if with_yaw is None else with_yaw) else [0, 1, 2]
        return np.eye(8)[rows]

    def _measurement(self, est: PoseEstimate, *, floor_factor: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        p = self.params
        z = np.zeros(8)
        z[:3] = est.pose.position
        yaw = float(est.pose.rpy[2])
        if self.has_yaw and self._x is not None:  # the equivalent yaw nearest the track's
            yaw = float(self._x[3] + wrap_angle(yaw - self._x[3], self.symmetry))
        z[3] = yaw
        R = np.zeros((8, 8))
        cov = est.frame_cov if est.calibration_cov is None else est.frame_cov - est.calibration_cov  # (the bias aside)
        w, V = np.linalg.eigh(cov)
        R[:3, :3] = V @ np.diag((np.sqrt(np.maximum(w, 0.0)) + floor_factor * p.position_floor_m) ** 2) @ V.T
        R[3, 3] = (np.sqrt(max(float(est.rpy_cov[2, 2]), 0.0)) + floor_factor * p.yaw_floor_rad) ** 2
        return z, R

    def _start(self, z: np.ndarray, R: np.ndarray, time_s: float, with_yaw: bool = True) -> None:
        self._x = z.copy()
        self._x[4:] = 0.0
        P = self._velocity_prior()
        P[:4, :4] = R[:4, :4]
        if not (self.has_yaw and with_yaw):
            P[3, 3] = np.pi**2
        self._P = P
        self._t = time_s
        self._last_accept_s = time_s
        self._runs.clear()
        self.accepted += 1

    def _propagate(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        assert self._x is not None
        F = np.eye(8)
        F[:4, 4:] = np.eye(4) * dt
        p = self.params
        q = (
            np.array([p.accel_sigma_m_s2, p.accel_sigma_m_s2, p.vertical_accel_sigma_m_s2, p.yaw_accel_sigma_rad_s2])
            ** 2
        )
        Q = np.zeros((8, 8))
        Q[:4, :4] = np.diag(q * dt**3 / 3.0)
        Q[:4, 4:] = Q[4:, :4] = np.diag(q * dt**2 / 2.0)
        Q[4:, 4:] = np.diag(q * dt)
        return F @ self._x, F @ self._P @ F.T + Q

    def _velocity_prior(self) -> np.ndarray:
        """The prior covariance of the rates when a track starts (8x8, zero but for the rates)."""
        p = self.params
        P = np.zeros((8, 8))
        P[4:7, 4:7] = (
            np.diag([p.initial_speed_sigma_m_s, p.initial_speed_sigma_m_s, p.initial_vertical_speed_sigma_m_s]) ** 2
        )
        P[7, 7] = p.initial_yaw_rate_sigma_rad_s**2
        return P

    def _jump_fit(self, rejected: list) -> tuple[np.ndarray, np.ndarray, bool] | None:
        """The last ``jump_confirm`` rejected estimates in a row (of one camera), if they fit one constant-velocity
        motion: its state (pose and rates at the newest) and covariance, and whether it has a yaw.

        Weighted least squares of ``z_i = p + v (t_i - t_n)`` with the rates' prior as a pseudo
        measurement; accepted when the residuals' chi-square is within its 99.9 % quantile.
        """
        n = self.params.jump_confirm
        if len(rejected) < n:
            return None
        run = rejected[-n:]
        with_yaw = all(w for *_, w in run)
        rows = [0, 1, 2, 3] if with_yaw else [0, 1, 2]
        m = len(rows)
        idx = rows + [r + 4 for r in rows]
        t_n = run[-1][0]
        prior = self._velocity_prior()
        prior_info = np.linalg.inv(prior[np.ix_(idx[m:], idx[m:])])
        info = np.zeros((2 * m, 2 * m))
        info[m:, m:] = prior_info
        vec = np.zeros(2 * m)
        blocks = []
        for t, z, R, _ in run:
            A = np.hstack([np.eye(m), (t - t_n) * np.eye(m)])
            zi = z[rows].copy()
            if with_yaw:  # the equivalent yaw nearest the newest's
                zi[3] = run[-1][1][3] + wrap_angle(zi[3] - run[-1][1][3], self.symmetry)
            W = np.linalg.inv(R[np.ix_(rows, rows)])
            info += A.T @ W @ A
            vec += A.T @ W @ zi
            blocks.append((A, zi, W))
        cov = np.linalg.inv(info)
        sol = cov @ vec
        chi2 = sum(float((zi - A @ sol) @ W @ (zi - A @ sol)) for A, zi, W in blocks)
        chi2 += float(sol[m:] @ prior_info @ sol[m:])  # the rates against their prior
        if chi2 > CHI2_999[(n - 1) * m]:
            return None
        x = np.zeros(8)
        x[idx] = sol
        if not with_yaw:
            x[3] = run[-1][1][3]
        P = self._velocity_prior()
        P[np.ix_(idx, idx)] = cov
        if not (self.has_yaw and with_yaw):
            P[3, 3] = np.pi**2
        return x, P, with_yaw

    def _restart(self, x: np.ndarray, P: np.ndarray, with_yaw: bool, time_s: float) -> None:
        self._x, self._P, self._t = x, 0.5 * (P + P.T), time_s
        self._last_accept_s = time_s
        self._runs.clear()
        self.accepted += 1
