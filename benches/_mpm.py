"""MLS-MPM in Taichi on the CPU (``ti.init(arch=ti.x64)``): the peer solver of the particle
benches (benches/peer_mpm.py: an elastic cube; benches/sand.py: a sand column;
benches/dam_break.py: a water column; benches/honey_peers.py: a hanging blob of honey), one
transfer loop with five constitutive models.

Written for these benches from the published algorithms, not copied:
- MLS-MPM transfers (Hu et al. 2018, "A moving least squares material point method", eq. 16-18)
  with APIC affine velocities, quadratic B-spline weights, one particle-to-grid and one
  grid-to-particle pass per step, explicit time steps ``dt = cfl dx / c`` with ``c`` the
  material's wave speed;
- ``"elastic"``: fixed-corotated hyperelasticity (Stomakhin et al. 2012), Kirchhoff stress
  ``tau = 2 mu (F - R) F^T + lam J (J - 1) I`` with the Lame parameters of (E, nu);
- ``"sand"``: Drucker-Prager elastoplasticity of dry sand after Klar et al. 2016 ("Drucker-
  Prager elastoplasticity for sand animation", sections 4-7): the elastic part of the
  deformation gradient ``F = U Sigma V^T`` in Hencky strain ``eps = log Sigma``; St. Venant-
  Kirchhoff in Hencky strain, ``tau = U (2 mu eps + lam tr(eps) I) U^T``; the return map
  projects ``eps`` onto the cone ``|eps_dev| <= -alpha (3 lam + 2 mu) / (2 mu) tr(eps)`` with
  ``alpha = sqrt(2/3) 2 sin(phi) / (3 - sin(phi))`` and sends a state in tension
  (``tr eps >= 0``) to the apex ``eps = 0`` (no cohesion);
- ``"water"``: a weakly compressible liquid (Monaghan's convention: a speed of sound ``c``
  about ten times the flow's, so the density varies by about 1 %), the volume ratio ``J``
  carried per particle (``J <- J (1 + dt tr C)``), pressure ``p = K (1 - J)`` with
  ``K = rho c^2`` clamped at zero in tension (a free surface does not pull), Kirchhoff stress
  ``tau = -p J I``; no viscosity (water's 1e-3 Pa s is far below this grid's numerical one);
- ``"viscous"``: a weakly compressible Newtonian liquid, the same ``J`` and ``K`` but the
  pressure two-sided (``p = K (1 - J)`` in tension too, as a liquid under the atmosphere's
  pressure holds its volume when pulled) and a shear viscosity ``mu``: Kirchhoff stress
  ``tau = J (-p I + 2 mu dev D)``, ``D = (C + C^T) / 2`` the particle's velocity gradient's
  symmetric part (APIC's ``C`` is the MLS-MPM velocity gradient, Hu et al. 2018 section 5.3);
- ``"honey"``: the same plus an elastic deviatoric stress with a von Mises yield (a Bingham-like
  viscoelastic-viscoplastic liquid, in the spirit of Yue et al. 2015, "Continuum foam", without
  their Herschel-Bulkley hardening): an isochoric elastic ``F_e`` updated by ``(I + dt C)``,
  ``F_e = U Sigma V^T``, the Hencky strain's deviator ``e = log Sigma - mean`` returned onto the
  cylinder ``2 G |e| <= sqrt(2/3) sigma_y`` (uniaxial yield stress ``sigma_y``), ``F_e <- U
  exp(e) V^T``, and ``tau += U 2 G e U^T``.

Boundaries: the grid box's outer three cells stop the velocity into them (slip walls at the
box's faces, ``origin + 3 dx`` and ``origin + extent - 3 dx``), and the bottom face is a floor
with Coulomb friction ``floor_friction`` (``0``: slip). With ``ceiling`` (m), every grid node at
or above that height is sticky (its velocity zero, no-slip and holding in tension): a glued
lid. Units SI.
"""

from __future__ import annotations

import math
import time

import numpy as np

GRAVITY = 9.81
PADDING = 3  # grid cells outside the walls (the B-spline stencil reaches 2)


class Mpm:
    """Particles of one material stepped by MLS-MPM.

    positions: (N, 3) particles (m), each of volume ``volume`` (m^3) and density ``density``
    (kg/m^3); ``dx`` the grid spacing (m); ``low``, ``high`` the walls' corners (m; the floor
    at ``low[2]``); ``material`` ``"elastic"`` (needs ``young`` Pa, ``nu``), ``"sand"`` (also
    ``friction_angle`` in degrees), ``"water"`` (``sound_speed`` m/s), ``"viscous"`` (also
    ``viscosity`` Pa s) or ``"honey"`` (also ``shear_modulus`` and ``yield_stress``, Pa);
    ``floor_friction`` the floor's Coulomb coefficient; ``ceiling`` (m, None: none) the height
    from which grid nodes are sticky, on a grid node (``ceiling - low[2]`` a multiple of
    ``dx``); ``cfl`` the step's fraction of a cell per wave crossing (with a viscosity, the
    step is also at most ``rho dx^2 / (10 mu)``, explicit diffusion's limit with a margin);
    ``threads`` for Taichi."""

    def __init__(self, positions, *, volume, density, dx, low, high, material, young=0.0,
                 nu=0.0, friction_angle=0.0, sound_speed=0.0, floor_friction=0.0, cfl=0.4,
                 threads=2, viscosity=0.0, shear_modulus=0.0, yield_stress=1.0, ceiling=None):
        import taichi as ti

        ti.init(arch=ti.x64, cpu_max_num_threads=threads, default_fp=ti.f32,
                offline_cache=True, log_level=ti.WARN)
        if material not in ("elastic", "sand", "water", "viscous", "honey"):
            raise ValueError(f"material = {material!r}: elastic, sand, water, viscous or honey")
        liquid = material in ("water", "viscous", "honey")
        self.ti = ti
        self.n = len(positions)
        self.dx = dx
        if liquid:
            mu, lam, bulk = 0.0, 0.0, density * sound_speed ** 2
            wave = math.sqrt((bulk + 4.0 / 3.0 * shear_modulus) / density)
        else:
            mu = young / (2 * (1 + nu))
            lam = young * nu / ((1 + nu) * (1 - 2 * nu))
            bulk, wave = 0.0, math.sqrt((lam + 2 * mu) / density)
        self.dt = cfl * dx / wave
        if viscosity > 0.0:
            self.dt = min(self.dt, density * dx * dx / (10.0 * viscosity))
        g_e, visc = shear_modulus, viscosity
        e_max = math.sqrt(2.0 / 3.0) * yield_stress / (2.0 * max(shear_modulus, 1e-30))
        self.origin = np.asarray(low, dtype=float) - PADDING * dx
        extent = np.asarray(high, dtype=float) - np.asarray(low, dtype=float) + 2 * PADDING * dx
        self.cells = tuple(int(np.ceil(e / dx)) for e in extent)
        sticky = (self.cells[2] + 1 if ceiling is None
                  else int(round((ceiling - self.origin[2]) / dx)))
        s = math.sin(math.radians(friction_angle))
        alpha = math.sqrt(2.0 / 3.0) * 2.0 * s / (3.0 - s)
        self.x = ti.Vector.field(3, ti.f32, self.n)
        self.v = ti.Vector.field(3, ti.f32, self.n)
        self.C = ti.Matrix.field(3, 3, ti.f32, self.n)
        self.F = ti.Matrix.field(3, 3, ti.f32, self.n)
        self.J = ti.field(ti.f32, self.n)
        self.grid_v = ti.Vector.field(3, ti.f32, self.cells)
        self.grid_m = ti.field(ti.f32, self.cells)
        inv_dx, dt = 1.0 / dx, self.dt
        p_mass, p_vol = density * volume, volume
        g, mu_f = GRAVITY, floor_friction
        x, v, C_, F, J_ = self.x, self.v, self.C, self.F, self.J
        grid_v, grid_m = self.grid_v, self.grid_m
        origin = ti.Vector(list(self.origin.astype(np.float32)))
        self.positions0 = np.asarray(positions, dtype=np.float32)

        @ti.func
        def weights(xp):
            base = int(xp - 0.5)
            fx = xp - base
            return base, fx, [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]

        @ti.func
        def sand_return(sig):
            """Klar et al. 2016, section 7: the singular values of the elastic F after the
            return to the Drucker-Prager cone (the apex in tension)."""
            eps = ti.Vector([ti.log(ti.max(sig[i, i], 1e-6)) for i in ti.static(range(3))])
            tr = eps.sum()
            out = ti.Vector([1.0, 1.0, 1.0])
            if tr < 0.0:
                dev = eps - tr / 3.0
                norm = dev.norm() + 1e-20
                gamma = norm + (3.0 * lam + 2.0 * mu) / (2.0 * mu) * tr * alpha
                h = eps
                if gamma > 0.0:
                    h = eps - gamma / norm * dev
                out = ti.exp(h)
            return out

        @ti.func
        def kirchhoff(p):
            """Updates particle p's state by its velocity gradient and returns its Kirchhoff
            stress (Pa)."""
            tau = ti.Matrix.zero(ti.f32, 3, 3)
            eye = ti.Matrix.identity(ti.f32, 3)
            if ti.static(liquid):
                J_[p] *= 1.0 + dt * C_[p].trace()
                pressure = bulk * (1.0 - J_[p])
                if ti.static(material == "water"):
                    pressure = ti.max(0.0, pressure)
                tau = -pressure * J_[p] * eye
                if ti.static(material != "water"):
                    D = 0.5 * (C_[p] + C_[p].transpose())
                    tau += J_[p] * 2.0 * visc * (D - D.trace() / 3.0 * eye)
                if ti.static(material == "honey"):
                    U, sig, V = ti.svd((eye + dt * C_[p]) @ F[p])
                    e = ti.Vector([ti.log(ti.max(sig[i, i], 1e-6)) for i in ti.static(range(3))])
                    e -= e.sum() / 3.0
                    norm = e.norm()
                    if norm > e_max:
                        e *= e_max / norm
                    F[p] = U @ ti.Matrix([[ti.exp(e[0]), 0, 0], [0, ti.exp(e[1]), 0],
                                          [0, 0, ti.exp(e[2])]]) @ V.transpose()
                    d = 2.0 * g_e * e
                    tau += U @ ti.Matrix([[d[0], 0, 0], [0, d[1], 0], [0, 0, d[2]]]) @ U.transpose()
            elif ti.static(material == "sand"):
                U, sig, V = ti.svd((ti.Matrix.identity(ti.f32, 3) + dt * C_[p]) @ F[p])
                s_new = sand_return(sig)
                F[p] = U @ ti.Matrix([[s_new[0], 0, 0], [0, s_new[1], 0], [0, 0, s_new[2]]]) @ V.transpose()
                eps = ti.log(s_new)
                d = 2.0 * mu * eps + lam * eps.sum()
                tau = U @ ti.Matrix([[d[0], 0, 0], [0, d[1], 0], [0, 0, d[2]]]) @ U.transpose()
            else:
                F[p] = (ti.Matrix.identity(ti.f32, 3) + dt * C_[p]) @ F[p]
                R, _ = ti.polar_decompose(F[p])
                J = F[p].determinant()
                tau = 2.0 * mu * (F[p] - R) @ F[p].transpose() + ti.Matrix.identity(ti.f32, 3) * lam * J * (J - 1.0)
            return tau

        @ti.kernel
        def substep():
            for I in ti.grouped(grid_m):
                grid_v[I] = ti.Vector.zero(ti.f32, 3)
                grid_m[I] = 0.0
            for p in x:
                base, fx, w = weights((x[p] - origin) * inv_dx)
                tau = kirchhoff(p)
                affine = -dt * p_vol * 4.0 * inv_dx * inv_dx * tau + p_mass * C_[p]
                for i, j, k in ti.static(ti.ndrange(3, 3, 3)):
                    offset = ti.Vector([i, j, k])
                    dpos = (offset.cast(ti.f32) - fx) * dx
                    weight = w[i][0] * w[j][1] * w[k][2]
                    grid_v[base + offset] += weight * (p_mass * v[p] + affine @ dpos)
                    grid_m[base + offset] += weight * p_mass
            for I in ti.grouped(grid_m):
                if grid_m[I] > 0:
                    gv = grid_v[I] / grid_m[I]
                    gv[2] -= dt * g
                    if I[2] < PADDING + 1 and gv[2] < 0:
                        # Coulomb friction on the floor: the tangential speed drops by mu |v_n|.
                        tangent = ti.Vector([gv[0], gv[1], 0.0])
                        speed = tangent.norm()
                        keep = ti.max(0.0, 1.0 - mu_f * (-gv[2]) / (speed + 1e-20))
                        gv = tangent * keep
                    if I[2] >= sticky:
                        gv = ti.Vector.zero(ti.f32, 3)
                    for d in ti.static(range(3)):
                        if I[d] < PADDING and gv[d] < 0:
                            gv[d] = 0.0
                        if I[d] > grid_m.shape[d] - PADDING - 1 and gv[d] > 0:
                            gv[d] = 0.0
                    grid_v[I] = gv
            for p in x:
                base, fx, w = weights((x[p] - origin) * inv_dx)
                new_v = ti.Vector.zero(ti.f32, 3)
                new_C = ti.Matrix.zero(ti.f32, 3, 3)
                for i, j, k in ti.static(ti.ndrange(3, 3, 3)):
                    offset = ti.Vector([i, j, k])
                    dpos = offset.cast(ti.f32) - fx
                    weight = w[i][0] * w[j][1] * w[k][2]
                    gv = grid_v[base + offset]
                    new_v += weight * gv
                    new_C += 4.0 * inv_dx * weight * gv.outer_product(dpos)
                v[p], C_[p] = new_v, new_C
                x[p] += dt * new_v

        self.substep = substep

    def reset(self) -> None:
        self.x.from_numpy(self.positions0)
        self.v.fill(0.0)
        self.C.fill(0.0)
        self.J.fill(1.0)
        self.F.from_numpy(np.tile(np.eye(3, dtype=np.float32), (self.n, 1, 1)))

    def timed(self, seconds: float) -> tuple:
        """After a warm-up, steps for ``seconds`` (s) from the initial state: (steps, wall s)."""
        self.warm_up()
        t = time.perf_counter()
        steps = self.advance(seconds)
        return steps, time.perf_counter() - t

    def warm_up(self) -> None:
        """Compiles the kernels by 20 steps (so a timed run leaves out the compilation) and
        restarts from the initial state."""
        self.reset()
        self.advance(20 * self.dt)
        self.reset()

    def advance(self, seconds: float) -> int:
        """Steps for ``seconds`` (s); returns the steps taken."""
        steps = int(np.ceil(seconds / self.dt))
        for _ in range(steps):
            self.substep()
        self.ti.sync()
        return steps

    def positions(self) -> np.ndarray:
        return self.x.to_numpy().astype(np.float64)


def sand_column(positions, *, spacing, radius, height, density, young, friction_angle,
                floor_friction, threads):
    """A sand column's particles (m, one per lattice site of ``spacing`` m, volume spacing^3)
    of ``radius`` and ``height`` (m) on a floor at z = 0: Drucker-Prager sand (E ``young`` Pa,
    nu 0.3, ``friction_angle`` degrees) on a grid of twice the spacing reaching 3.5 radii
    from the axis and 1.3 heights up, the floor's Coulomb coefficient ``floor_friction``."""
    reach = 3.5 * radius
    return Mpm(positions, volume=spacing ** 3, density=density, dx=2 * spacing,
               low=(-reach, -reach, 0.0), high=(reach, reach, 1.3 * height), material="sand",
               young=young, nu=0.3, friction_angle=friction_angle,
               floor_friction=floor_friction, threads=threads)
