"""Seed 003: path-constrained planning in the (θ, θ̇) phase plane with the telescope as a
function of the path parameter, and the re-planning to start (and end) at rest.

The tip follows a path p(θ) given in the seed's own parameter θ (not arc length;
:class:`~planner.geometry.paths.SeedPath`):

- circle (seed eq. 4–5, :func:`circle_path`): p(θ) = (xC + R cos θ, 0, zC + R sin θ),
  θ = atan2(z − zC, x − xC) ∈ [−π, π], R = 0.7 m, (xC, zC) = (3, 2.5) m;
- parabola (seed eq. 6–8, :func:`parabola_path`): θ = x ∈ [x0, xend] = [1.6, 3.07] m,
  p(θ) = (θ, tan α·θ, (θ − h)²/(4a) + k), h = (x0 + xend)/2, k = zmax,
  a = (x0 − h)²/(4(zmin − k)) < 0. The seed prints (θ + h); only (θ − h) puts the vertex
  (z = zmax) mid-path and z = zmin at both ends (``vertex="plus"`` gives the printed form).

One module per job:

- :mod:`~planner.methods.phase.telescope`: the telescope q4 = φ4(θ) (Fourier on the circle,
  Bézier on the parabola), :func:`optimise_telescope` (maximum area under the envelope),
  :func:`seed_setup`;
- :mod:`~planner.methods.phase.envelope`: Φ(θ), Φ'(θ), the velocity envelope, the feasible
  telescope band, the constant-telescope scan and the time-efficient :class:`Profile`;
- :mod:`~planner.methods.phase.from_rest`: the Ruckig transitions from and to rest
  (:func:`from_rest`).

The method plans along a given seed curve, not from a start to a goal tip, so it is not a
registered :class:`~planner.methods.base.Planner` (a :class:`~planner.methods.base.PlanRequest`
has no way to name the curve and its telescope model).
"""
from planner.geometry.paths import SeedPath, circle_path, parabola_path
from planner.methods.phase.envelope import (CLAIMS, Envelope, Profile, constant_scan, envelope,
                                            feasible_band, joint_path, path_states,
                                            rate_bounds, tele_grid, time_efficient_profile)
from planner.methods.phase.from_rest import FromRest, Junction, from_rest
from planner.methods.phase.telescope import (BezierTele, FourierTele, TeleOpt,
                                             optimise_telescope, seed_setup)

__all__ = ["SeedPath", "circle_path", "parabola_path", "FourierTele", "BezierTele",
           "joint_path", "rate_bounds", "envelope", "Envelope", "feasible_band",
           "constant_scan", "optimise_telescope", "TeleOpt", "time_efficient_profile",
           "Profile", "from_rest", "FromRest", "Junction", "seed_setup", "CLAIMS",
           "path_states", "tele_grid"]
