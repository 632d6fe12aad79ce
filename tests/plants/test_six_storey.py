"""The six-storey building with four dampers (two in storey 1, two in storey 2; preset ``six_storey``): its modes
against the closed form of a uniform shear chain, its coupled 1 kHz response against Radau, at rest at rest."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import eigh

from mrd_env import make_damper
from mrd_env.disturbances import el_centro
from mrd_env.plants.shear_building import shear_building

from tests.plants.test_plants import DT, run_plant, sd_terms
from tests.reference_models import nrmse

N, MASS, STOREY_K = 6, 200.0, 1.2e6  # the preset's documented floors and storeys (physics.SIX_STOREY)


def closed_form_frequencies() -> np.ndarray:
    """A uniform fixed-free shear chain of n equal masses m and storeys k: ω_r = 2·√(k/m)·sin((2r−1)π/(2(2n+1)))."""
    r = np.arange(1, N + 1)
    return 2 * np.sqrt(STOREY_K / MASS) * np.sin((2 * r - 1) * np.pi / (2 * (2 * N + 1)))


def test_six_storey_modes_match_the_closed_form_and_its_damping_is_half_a_percent_in_modes_1_and_2():
    b = shear_building("six_storey")
    assert b.damper_floors == (1, 1, 2, 2) and b.n_floors == 6
    lp = b.plant()
    w2, V = eigh(lp.K, lp.M)
    w = np.sqrt(w2)
    np.testing.assert_allclose(w, closed_form_frequencies(), rtol=1e-10)
    assert w[0] / (2 * np.pi) == pytest.approx(2.972, abs=1e-3)  # the docstring's 2.97 Hz
    zeta = np.diag(V.T @ lp.C @ V) / (2 * w)  # eigh's modes are mass-normalised
    np.testing.assert_allclose(zeta[:2], 0.005, rtol=1e-9)
    assert np.all(zeta[2:] > 0.005)  # Rayleigh: more damping in the higher modes


def test_six_storey_building_at_rest_stays_at_rest_with_its_four_preloaded_dampers():
    d = make_damper("spencer_dyke", "spencer1997")
    F, Y, _ = run_plant(shear_building("six_storey"), d, np.zeros((501, 1)), 2.25)
    assert F.shape[1] == 4
    assert np.max(np.abs(Y[:, :6])) < 1e-12


@pytest.mark.slow  # about 20 s of Radau on 30 stiff states
def test_six_storey_building_with_four_spencer_dyke_dampers_matches_radau_on_el_centro():
    b = shear_building("six_storey")
    d = make_damper("spencer_dyke", "spencer1997")
    p, V, T = d.params, 1.0, 1.0  # 1 s: El Centro's first 5 s replayed 5× faster, its strongest motion in them
    w = el_centro("NS", time_scale=0.2, dt=DT).data[: int(T / DT) + 1]
    F, Y, _ = run_plant(b, d, w, V)
    # the building written out independently: equal floors, equal storeys, Rayleigh damping of 0.5 % in modes 1, 2
    K = STOREY_K * (2 * np.eye(N) - np.eye(N, k=1) - np.eye(N, k=-1))
    K[-1, -1] = STOREY_K
    w1, w2 = closed_form_frequencies()[:2]
    a0, a1 = 2 * 0.005 * w1 * w2 / (w1 + w2), 2 * 0.005 / (w1 + w2)
    C = a0 * MASS * np.eye(N) + a1 * K
    S = np.zeros((4, N))  # dampers 1, 2 between ground and floor 1; 3, 4 between floors 1 and 2
    S[:2, 0] = 1.0
    S[2:, 1], S[2:, 0] = 1.0, -1.0
    F_static, eta = -p.k1 * p.x0, d.command.eta
    t_grid = np.arange(len(w)) * DT

    def full(t, s):
        x, v = s[:N], s[N:2 * N]
        y, z, u = s[2 * N:2 * N + 4], s[2 * N + 4:2 * N + 8], s[2 * N + 8:]
        yd, zd, Fd = sd_terms(p, u, S @ x, S @ v, y, z)
        a = (-C @ v - K @ x - S.T @ (Fd - F_static)) / MASS - np.interp(t, t_grid, w[:, 0])
        return np.concatenate([v, a, yd, zd, -eta * (u - V)])

    sol = solve_ivp(full, (0, T), np.zeros(2 * N + 12), method="Radau", rtol=1e-9, atol=1e-12, t_eval=t_grid[1:],
                    max_step=DT)
    assert sol.success
    x = sol.y[:N]
    drift_ref = np.vstack([x[0], np.diff(x, axis=0)])
    drift = np.vstack([Y[:, 0], np.diff(Y[:, :N].T, axis=0)])
    errors = [nrmse(drift[i], drift_ref[i]) for i in range(N)]
    assert max(errors) <= 0.01, errors
    s = sol.y
    _, _, F_ref = sd_terms(p, s[2 * N + 8:], S @ x, S @ s[N:2 * N], s[2 * N:2 * N + 4], s[2 * N + 4:2 * N + 8])
    force_errors = [nrmse(F[:, j], F_ref[j]) for j in range(4)]
    assert max(force_errors) <= 0.01, force_errors
    print(f"six-storey vs Radau: worst drift NRMSE {max(errors):.2e}, worst force NRMSE {max(force_errors):.2e}")


def test_six_storey_v1_is_unchanged():
    """building-six-storey-v1 is scored on this building: its floors, storeys and dampers stay as they were."""
    b = shear_building("six_storey")
    assert b.masses == (MASS,) * N and b.damper_floors == (1, 1, 2, 2)
    np.testing.assert_allclose(np.diag(b.K), [2 * STOREY_K] * 5 + [STOREY_K])
    assert b.record_time_scale == 0.2 and b.storey_heights == (0.3,) * N


def test_six_storey_v2_floors_are_sized_by_the_stated_rule():
    """The rule by hand: at full command the four prototype dampers of storey 2 (1 619.5 N each, half the peak-to-peak
    force of the reference page's check motion: 1 548 N and −1 691 N) hold the five floors storey 2 carries up to
    0.3 g: 4 · 1 619.5 = 5 · m · 0.3 · 9.80665, m = 440.38 kg; the storeys 6 000 N/m per kg keep v1's modes."""
    from mrd_env.plants.shear_building.physics import capacity_ratio, capacity_sized_floor_mass

    b = shear_building("six_storey_v2")
    assert b.damper_floors == (2, 2, 2, 2)
    m = 4 * 1619.5 / (5 * 0.3 * 9.80665)
    assert m == pytest.approx(440.38, abs=0.005)
    np.testing.assert_allclose(b.masses, [m] * N, rtol=1e-12)
    np.testing.assert_allclose(np.diag(b.K), [2 * 6000.0 * m] * 5 + [6000.0 * m], rtol=1e-12)
    assert capacity_ratio(b, 2) == pytest.approx(0.3, rel=1e-12) and capacity_ratio(b, 1) == 0.0
    # v1's layout sat near the rule by accident: 2 · 1 619.5 N over 6 · 200 kg in storey 1
    assert capacity_ratio(shear_building("six_storey"), 1) == pytest.approx(2 * 1619.5 / (1200 * 9.80665))
    assert capacity_sized_floor_mass(3, 2, 1, pga=9.80665) == pytest.approx(1619.5 / (2 * 9.80665))
    w_v1 = np.sqrt(eigh(shear_building("six_storey").K, np.diag(shear_building("six_storey").masses),
                        eigvals_only=True))
    w_v2 = np.sqrt(eigh(b.K, np.diag(b.masses), eigvals_only=True))
    np.testing.assert_allclose(w_v2, w_v1, rtol=1e-12)
    with pytest.raises(ValueError, match="storey"):
        capacity_ratio(b, 7)


def test_storeys_option_six_still_names_the_v1_building():
    from mrd_env.plants.shear_building.profile import _apply_plant_options

    out = _apply_plant_options({}, {"storeys": "6"})
    assert out["plant_preset"] == "six_storey" and out["damper_floors"] == [1, 1, 2, 2]
