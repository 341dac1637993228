#!/usr/bin/env python3
"""The restitution a head-on collision gets from two velocity-Verlet integrations of the linear
spring-dashpot (docs/cell_validation.md, "Powder 0.125 d at load 1"): the dashpot on millflow's
velocity, predicted at the step's end from the last force, or on LAMMPS's half-step velocity.
The contact is over when the overlap returns to zero, as in both codes; the normal force may pull
in its damped tail. One dimension, two bodies, no rotation.

Usage: bench/restitution_schemes.py   (the cement cell's media-powder pair, then a table of the
relative error in e against steps per undamped half period)
"""
import math


def restitution(scheme, e, mass_a, mass_b, stiffness, dt):
    zeta = -math.log(e) / math.sqrt(math.pi**2 + math.log(e) ** 2)
    m_eff = mass_a * mass_b / (mass_a + mass_b)
    damping = 2 * zeta * math.sqrt(stiffness * m_eff)
    x_a = x_b = 0.0  # just touching: the overlap is x_a - x_b
    v_a, v_b, force = 0.5, -0.5, 0.0  # force on a, along +x
    touched = False
    while True:
        v_a += force / mass_a * dt / 2
        v_b -= force / mass_b * dt / 2
        x_a += v_a * dt
        x_b += v_b * dt
        overlap = x_a - x_b
        if overlap > 0:
            closing = v_a - v_b
            if scheme == "millflow":
                closing += force * dt / (2 * m_eff)
            force = -(stiffness * overlap + damping * closing)
            touched = True
        else:
            force = 0.0
        v_a += force / mass_a * dt / 2
        v_b -= force / mass_b * dt / 2
        if touched and overlap <= 0:
            return v_b - v_a  # impact speed 1 m/s


def sphere_mass(density, diameter):
    return density * math.pi / 6 * diameter**3


ball, grain = sphere_mass(7800, 0.05), sphere_mass(3150, 0.00625)
stiffness, cell_dt = 1.6e6, 9.899e-7
for scheme in ("millflow", "lammps"):
    print(f"{scheme:8s} media-powder e 0.3 at the cell's dt: "
          f"{restitution(scheme, 0.3, ball, grain, stiffness, cell_dt):.6f}")
print("relative error in e, steps per undamped half period 20 40 54 80 160:")
for e in (0.2, 0.3, 0.5, 0.9):
    for scheme in ("millflow", "lammps"):
        errors = []
        for steps in (20, 40, 54, 80, 160):
            dt = math.pi * math.sqrt(grain / stiffness) / steps
            errors.append(f"{restitution(scheme, e, ball, grain, stiffness, dt) / e - 1:+.4f}")
        print(f"  e {e}  {scheme:8s} " + " ".join(errors))
