"""Full car (7 degrees of freedom) with an MR damper at each corner.

Coordinates q = [z_s, θ, φ, z_fl, z_fr, z_rl, z_rr], from static equilibrium: the heave of the body's centre of
mass (up), its pitch θ (rad, positive nose down: the body above the front axle is at z_s − a θ, as the half car)
and roll φ (rad, positive left side up: the body above the left wheels is at z_s + (t/2) φ; x forward, y left,
z up), and the four unsprung masses (front left, front right, rear left, rear right: the corners' order
everywhere). The suspension strokes, extension positive, are x = S q::

    x_fl = z_s − a θ + (t_f/2) φ − z_fl        x_fr = z_s − a θ − (t_f/2) φ − z_fr
    x_rl = z_s + b θ + (t_r/2) φ − z_rl        x_rr = z_s + b θ − (t_r/2) φ − z_rr

(a, b the distances of the front and rear axles from the centre of mass, t_f, t_r the tracks). Each corner has a
spring k_s, an MR damper (force F, positive resisting extension) and an optional viscous damper c_p across its
stroke, and a tyre k_t, c_t between its wheel and its road z_r. An anti-roll bar of roll stiffness k_ar (N·m/rad)
resists the body's roll relative to its axle, (x_left − x_right)/t: the energy ½ k_ar ((x_l − x_r)/t)². Then::

    M q̈ + C q̇ + K q = −Sᵀ F + E w,    M = diag(m_s, I_y, I_x, m_uf, m_uf, m_ur, m_ur)
    K = Sᵀ K_s S + Σ_axles k_ar D_axleᵀ D_axle + diag(0, 0, 0, k_t),   C = Sᵀ C_p S + diag(0, 0, 0, c_t)

with D_axle = (S_left − S_right)/t and w = [z_rfl, ż_rfl, z_rfr, ż_rfr, z_rrl, ż_rrl, z_rrr, ż_rrr] the roads
under the four wheels (E: k_t z_r + c_t ż_r on each wheel). The damper's static preload is balanced by the springs'
static deflection (:class:`~mrd_env.mechanics.CoupledPlant`), so that q = 0 is the car at rest on a flat road.

The parameter set "sedan" is the 7-DOF passenger car of the full-car suspension literature: m_s 1460 kg, roll
inertia I_x 460 kg·m², pitch inertia I_y 2460 kg·m², unsprung masses 40 kg (front) and 35.5 kg (rear) each,
springs 19 960 N/m (front) and 17 500 N/m (rear), tyres 175 500 N/m and 14.6 N·s/m, a = 1.011 m, b = 1.803 m,
track 1.51 m, passive dampers 1290 N·s/m (front) and 1620 N·s/m (rear). Read from Table 2 of "Equivalent Air
Spring Suspension Model for Quarter-Passive Model of Passenger Vehicles" (ISRN Mechanical Engineering 2015,
article 974020, Hindawi) as stored in this project's search corpus, and the same values (without track and roll
inertia) in the half-car parameter file of the public repository junhyukch7/Semi-Active-Suspension; commonly
attributed to Ikenaga, Lewis, Campos & Davis, "Active suspension control of ground vehicle based on a full-vehicle
model" (ACC 2000) — the original was not checked: **unverified**. The rear passive damping is 1620 N·s/m in the
repository's file and reads 1690 N·s/m in the stored table; 1620 is used (it only sets the passive reference). The
set has no anti-roll bars (k_ar = 0; give ``k_arf``, ``k_arr`` to add them) and no passive damper beside the MR
dampers (c_p = 0). Its undamped modes: heave and pitch coupled at 1.00 Hz (mostly heave, the front more) and
1.27 Hz (mostly pitch, the rear more), roll 1.46 Hz; wheel hop 11.1 Hz (front) and 11.7 Hz (rear).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...constants import GRAVITY
from ...mechanics import LinearPlant, preset_with_overrides
from ...validation import check_scalar

#: The corners, in the order of every per-corner signal, command and road channel.
CORNERS = ("fl", "fr", "rl", "rr")
#: The coordinates' names (``LinearPlant.dof_names``).
DOF_NAMES = ("z_s", "theta", "phi", "z_fl", "z_fr", "z_rl", "z_rr")
#: The road channels: height and its rate under each wheel (m, m/s).
ROAD_CHANNELS = tuple(n for c in CORNERS for n in (f"z_r{c}", f"zdot_r{c}"))
ROAD_UNITS = ("m", "m/s") * 4


@dataclass(frozen=True)
class FullCarParams:
    m_s: float     # body (sprung) mass, kg
    I_x: float     # body roll inertia about its centre of mass, kg·m²
    I_y: float     # body pitch inertia about its centre of mass, kg·m²
    m_uf: float    # each front unsprung mass, kg
    m_ur: float    # each rear unsprung mass, kg
    k_sf: float    # each front suspension spring, N/m
    k_sr: float    # each rear suspension spring, N/m
    k_tf: float    # each front tyre, N/m
    k_tr: float    # each rear tyre, N/m
    a: float       # centre of mass to the front axle, m
    b: float       # centre of mass to the rear axle, m
    t_f: float     # front track, m
    t_r: float     # rear track, m
    c_tf: float = 0.0   # each front tyre's damping, N·s/m
    c_tr: float = 0.0   # each rear tyre's damping, N·s/m
    k_arf: float = 0.0  # front anti-roll bar, roll stiffness N·m/rad (0: none)
    k_arr: float = 0.0  # rear anti-roll bar, N·m/rad
    c_pf: float = 0.0   # passive damper beside each front MR damper, N·s/m
    c_pr: float = 0.0   # passive damper beside each rear MR damper, N·s/m
    passive_cf: float = 0.0  # the set's conventional passive damper at each front corner (the reference), N·s/m
    passive_cr: float = 0.0  # ... at each rear corner, N·s/m
    source: str = ""

    def __post_init__(self) -> None:
        units = {"m": "kg", "I": "kg·m²", "k_s": "N/m", "k_t": "N/m"}
        for name in ("m_s", "I_x", "I_y", "m_uf", "m_ur", "k_sf", "k_sr", "k_tf", "k_tr", "a", "b", "t_f", "t_r"):
            unit = next((u for p, u in units.items() if name.startswith(p)), "m")
            check_scalar(f"FullCarParams.{name}", getattr(self, name), 0.0, lo_open=True, unit=unit)
        for name in ("c_tf", "c_tr", "c_pf", "c_pr", "passive_cf", "passive_cr"):
            check_scalar(f"FullCarParams.{name}", getattr(self, name), 0.0, unit="N·s/m")
        for name in ("k_arf", "k_arr"):
            check_scalar(f"FullCarParams.{name}", getattr(self, name), 0.0, unit="N·m/rad")

    @property
    def wheelbase(self) -> float:
        return self.a + self.b

    @property
    def static_tyre_loads(self) -> np.ndarray:
        """The static load of each tyre (fl, fr, rl, rr), N: half the body's weight on each axle (b/L front, a/L
        rear) and the wheel's own."""
        g, L = GRAVITY, self.wheelbase
        front = 0.5 * self.m_s * g * self.b / L + self.m_uf * g
        rear = 0.5 * self.m_s * g * self.a / L + self.m_ur * g
        return np.array([front, front, rear, rear])

    @property
    def passive_damping(self) -> np.ndarray:
        """The set's reference passive damper at each corner (fl, fr, rl, rr), N·s/m."""
        return np.array([self.passive_cf, self.passive_cf, self.passive_cr, self.passive_cr])

    def body_at_corners(self) -> np.ndarray:
        """(4, 7): the body's vertical displacement above each corner from q (the strokes' body part)."""
        a, b, hf, hr = self.a, self.b, 0.5 * self.t_f, 0.5 * self.t_r
        B = np.zeros((4, 7))
        B[:, :3] = [[1.0, -a, hf], [1.0, -a, -hf], [1.0, b, hr], [1.0, b, -hr]]
        return B

    def plant(self) -> LinearPlant:
        S = self.body_at_corners()
        S[:, 3:] = -np.eye(4)
        ks = np.array([self.k_sf, self.k_sf, self.k_sr, self.k_sr])
        cp = np.array([self.c_pf, self.c_pf, self.c_pr, self.c_pr])
        kt = np.array([self.k_tf, self.k_tf, self.k_tr, self.k_tr])
        ct = np.array([self.c_tf, self.c_tf, self.c_tr, self.c_tr])
        K = S.T @ np.diag(ks) @ S
        for k_ar, left, right, track in ((self.k_arf, 0, 1, self.t_f), (self.k_arr, 2, 3, self.t_r)):
            D = (S[left] - S[right]) / track   # the body's roll relative to the axle
            K += k_ar * np.outer(D, D)
        C = S.T @ np.diag(cp) @ S
        K[3:, 3:] += np.diag(kt)
        C[3:, 3:] += np.diag(ct)
        E = np.zeros((7, 8))
        for i in range(4):
            E[3 + i, 2 * i], E[3 + i, 2 * i + 1] = kt[i], ct[i]
        M = np.diag([self.m_s, self.I_y, self.I_x, self.m_uf, self.m_uf, self.m_ur, self.m_ur])
        return LinearPlant(M=M, C=C, K=K, S=S, E=E, input_names=ROAD_CHANNELS, dof_names=DOF_NAMES,
                           mass_names=("m_s", "I_y", "I_x", "m_uf", "m_uf", "m_ur", "m_ur"))


#: The full car's parameter sets (see the module docstring for the source).
FULL_CAR_PRESETS = {
    "sedan": FullCarParams(m_s=1460.0, I_x=460.0, I_y=2460.0, m_uf=40.0, m_ur=35.5, k_sf=19960.0, k_sr=17500.0,
                           k_tf=175500.0, k_tr=175500.0, a=1.011, b=1.803, t_f=1.51, t_r=1.51, c_tf=14.6, c_tr=14.6,
                           passive_cf=1290.0, passive_cr=1620.0,
                           source="7-DOF sedan of the full-car suspension literature (ISRN Mech. Eng. 2015, "
                                  "974020, Table 2; attributed to Ikenaga et al., ACC 2000) (unverified)"),
}


def full_car(preset: str = "sedan", **overrides) -> FullCarParams:
    """A full-car parameter set by name, with optional overrides (SI)."""
    return preset_with_overrides(FULL_CAR_PRESETS, preset, "full-car", overrides)
