"""The frigate's response amplitude operators from a boundary-element solver (issue 70, item 1):
heave, roll and pitch per metre of wave amplitude, with their phases, for waves from 0-180 deg
off the bow, written as sim/data/frigate_rao.csv for deckwatch-sim's `hull-rao` ship-motion model
(sim/src/ship/hull_rao.rs; docs/ship-motion.md).

The hull is `ship::Hull::FRIGATE` (120 m waterline, 14 m beam, 4.5 m draft) given a generalised
Wigley form, fore-and-aft symmetric, with a sharp keel and stem:
    y = B/2 (1 - |2x/L|^3) (1 - |z/T|^q),
a waterplane coefficient of 0.75 (a frigate's) and the section's exponent q (about 2.44: a
midship coefficient of 0.71, a block coefficient of 0.53, 4100 t) chosen so that the hull's own
hydrostatics, with the centre of gravity amidships 1 m above the waterline (OG), give
deckwatch's GM of 1.2 m: the restoring and the waves' moment come from one consistent hull.
(A plain Wigley hull of these dimensions, 3400 t, has GM 1.05 m; fuller sections on its
parabolic waterplane bring GM to nothing: the waterplane's fullness is what keeps a beam this
narrow stable with G above the water.) The mass properties
are the ones deckwatch uses (sim/src/ship/hull.rs, docs/ship-motion.md):
- mass: the displaced water's (rho 1025 kg/m^3);
- roll: dry inertia such that, with the added inertia at the natural frequency, the radius of
  gyration is the IMO code's C B = 5.50 m (natural period 10.1 s, uncoupled);
- pitch and yaw: dry radius of gyration 0.25 L = 30 m; surge, sway, heave the mass.
The rotations are about the centre of gravity, so the heave is G's.

Potential flow has almost no roll damping (the radiated waves of a rolling ship are small): the
viscous share (eddies off the bilge and its keels, skin friction, the hull's lift at speed) is
added as a linear damping that brings the total at the natural frequency to 0.1 of critical, the
linear roll of the other models (the radiation's is 0.003, the viscous share 0.097, the
upper end of the 5-10 % usually added to a potential-flow roll).

Conventions: deckwatch's (docs/CONVENTIONS.md §2): x to the bow, y to port, z up; roll about x
(positive raises port), pitch about y (positive lowers the bow), as Capytaine's Roll and Pitch
dofs of a body so placed. The heading is where the waves come from off the bow, 0 head seas,
90 from port (beam), 180 following; Capytaine's wave_direction is where they go, 0 along +x
(checked in capytaine/bem/airy_waves.py: the incident potential goes as exp(i k (x cos beta +
y sin beta)), elevation 1 at the origin), so beta = 180 deg + heading. Capytaine's time factor
is exp(-i w t); the table's phase is the lead over the wave elevation at G:
    response(t) = amplitude a cos(w t + phase)   when the elevation at G is a cos(w t),
so phase = -arg(Capytaine's RAO). Waves from starboard (negative headings) roll the ship the
other way: the model uses the table's roll negated.

Zero speed, deep water. Solved with a lid on the waterplane (irregular frequencies removed) and
the hull's port-starboard symmetry.

Usage: /root/.cache/capytaine-venv/bin/python bench/hull_rao.py [--out sim/data/frigate_rao.csv]
       [--panels-x 60] [--panels-z 10]
Needs capytaine (pip install capytaine; 3.0.0 was used): about 2.5 minutes on one core for the
2400 triangles of 60 x 10 (40 x 6, 960 triangles, give the same table within 0.012 m/m of heave,
0.11 deg/m of roll, 0.018 deg/m of pitch, in 30 s).
"""

import argparse
import datetime
import math
import os
import time

# One core: the Green function's loops and the linear algebra threads otherwise take them all.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import scipy.optimize
import xarray as xr

import capytaine as cpt

RHO_KG_M3 = 1025.0
GRAVITY_MPS2 = 9.81
LENGTH_M, BEAM_M, DRAFT_M = 120.0, 14.0, 4.5
GM_M = 1.2
OG_M = 1.0
PITCH_GYRADIUS_M = 0.25 * LENGTH_M
YAW_GYRADIUS_M = 0.25 * LENGTH_M
# The roll's damping ratio at its natural frequency, radiation and viscous together: the 0.1 of
# the other models' linear roll (0.05-0.15 from decay tests of frigates with bilge keels).
ROLL_DAMPING_RATIO = 0.1
HEADINGS_DEG = np.arange(0.0, 180.1, 15.0)
# Denser about the roll resonance (0.62 rad/s), where linear interpolation between rows would
# otherwise cut the peak.
OMEGAS_RAD_S = np.round(
    np.concatenate([
        np.arange(0.20, 0.45, 0.05),
        np.arange(0.45, 0.80, 0.025),
        np.arange(0.80, 1.601, 0.05),
    ]),
    4,
)
DOFS = ["Surge", "Sway", "Heave", "Roll", "Pitch", "Yaw"]


def imo_roll_gyradius_m():
    """The IMO 2008 Intact Stability Code's C B (sim/src/ship/hull.rs `roll_gyradius_m`)."""
    c = 0.373 + 0.023 * BEAM_M / DRAFT_M - 0.043 * LENGTH_M / 100.0
    return c * BEAM_M


WATERPLANE_EXPONENT = 3.0


def half_breadth_m(x_m, z_m, section_exponent):
    """The hull's half breadth (m) at x (from amidships) and z (<= 0)."""
    xi = 2.0 * x_m / LENGTH_M
    zeta = z_m / DRAFT_M
    return 0.5 * BEAM_M * (1 - np.abs(xi) ** WATERPLANE_EXPONENT) * (1 - np.abs(zeta) ** section_exponent)


def port_half_mesh(panels_x, panels_z, section_exponent):
    """The port half of the wetted hull (y >= 0), triangles with normals into the water."""
    # Cosine spacing along the length: finer at the bow and stern, where the shape turns.
    xs = -0.5 * LENGTH_M * np.cos(np.linspace(0.0, math.pi, panels_x + 1))
    zs = np.linspace(-DRAFT_M, 0.0, panels_z + 1)
    vertices = np.array([[x, half_breadth_m(x, z, section_exponent), z] for x in xs for z in zs])
    index = lambda i, j: i * (panels_z + 1) + j  # noqa: E731
    # Triangles: the hull's quads would not be flat, and Capytaine's centre of a warped quad
    # depends on its vertices' order, which mirroring reverses (the halves' panels would sit
    # 5 cm apart and head seas would roll the ship).
    faces = []
    for i in range(panels_x):
        for j in range(panels_z):
            a, b, c, d = index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1)
            faces += [[a, b, c], [a, c, d]]
    # Where the keel meets the stem a triangle lies in the centre plane (no breadth: its mirror is
    # itself); the hull there is the other one.
    faces = [f for f in faces if np.abs(vertices[f, 1]).max() > 1e-9]
    mesh = cpt.Mesh(vertices, np.array(faces), name="frigate_port_half")
    # Normals out of the hull: to port on this half.
    if np.mean(mesh.faces_normals[:, 1]) < 0:
        mesh = cpt.Mesh(vertices, np.array(faces)[:, ::-1], name="frigate_port_half")
    return mesh


def port_half_lid(panels_x, panels_y, section_exponent):
    """The port half of the waterplane, a lid that removes the irregular frequencies (meshed
    here rather than by Capytaine's `generate_lid`, so that it keeps the hull's symmetry)."""
    xs = -0.5 * LENGTH_M * np.cos(np.linspace(0.0, math.pi, panels_x + 1))
    shares = np.linspace(0.0, 1.0, panels_y + 1)
    vertices = np.array([[x, s * half_breadth_m(x, 0.0, section_exponent), 0.0] for x in xs for s in shares])
    index = lambda i, j: i * (panels_y + 1) + j  # noqa: E731
    faces = []
    for i in range(panels_x):
        for j in range(panels_y):
            a, b, c, d = index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1)
            faces += [[a, b, c], [a, c, d]]
    # At the stem and stern the waterline has no breadth: the triangles with two corners there
    # have none either.
    area = lambda f: np.linalg.norm(np.cross(vertices[f[1]] - vertices[f[0]], vertices[f[2]] - vertices[f[0]]))  # noqa: E731
    faces = [f for f in faces if area(f) > 1e-9]
    return cpt.Mesh(vertices, np.array(faces), name="frigate_lid_port_half")


def hull_and_stiffness(panels_x, panels_z, section_exponent):
    """The floating hull (G amidships, OG above the waterline, its displaced mass), its
    hydrostatic stiffness (6 x 6, about G) and its GM (m)."""
    half = port_half_mesh(panels_x, panels_z, section_exponent)
    mesh = cpt.ReflectionSymmetricMesh(half, plane="xOz", name="frigate")
    cog = np.array([0.0, 0.0, OG_M])
    body = cpt.FloatingBody(
        mesh=mesh,
        lid_mesh=cpt.ReflectionSymmetricMesh(
            port_half_lid(panels_x, max(2, panels_z // 3), section_exponent), plane="xOz", name="lid"),
        dofs=cpt.rigid_body_dofs(rotation_center=cog),
        center_of_mass=cog,
        name="frigate",
    )
    body.mass = RHO_KG_M3 * body.volume
    c = np.array(body.compute_hydrostatic_stiffness(rho=RHO_KG_M3, g=GRAVITY_MPS2).values, dtype=float)
    gm_m = c[3, 3] / (RHO_KG_M3 * GRAVITY_MPS2 * body.volume)
    return half, body, c, gm_m


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default="sim/data/frigate_rao.csv")
    parser.add_argument("--panels-x", type=int, default=60, help="panels along the length")
    parser.add_argument("--panels-z", type=int, default=10, help="panels down each side")
    args = parser.parse_args()
    started = time.time()
    # Capytaine warns of each mesh the search for the hull below makes (the lid's normals turned
    # down); the panels' size against the shortest wave is printed below instead.
    cpt.set_logging("ERROR")

    # The section's exponent that gives the meshed hull GM 1.2 m (GM falls as the sections fill).
    section_exponent = scipy.optimize.brentq(
        lambda q: hull_and_stiffness(args.panels_x, args.panels_z, q)[3] - GM_M, 1.5, 4.0, xtol=1e-4)
    half, body, c, hull_gm_m = hull_and_stiffness(args.panels_x, args.panels_z, section_exponent)
    mesh = body.mesh
    volume_m3 = body.volume
    mass_kg = body.mass
    block = volume_m3 / (LENGTH_M * BEAM_M * DRAFT_M)
    print(f"hull: section exponent {section_exponent:.3f}; {mesh.nb_faces} panels ({half.nb_faces} per side), "
          f"lid {body.lid_mesh.nb_faces}; volume {volume_m3:.0f} m^3, block coefficient {block:.3f}, "
          f"displacement {mass_kg / 1e3:.0f} t; centre of buoyancy z {body.center_of_buoyancy[2]:.2f} m; "
          f"GM {hull_gm_m:.3f} m, GM_L {c[4, 4] / (RHO_KG_M3 * GRAVITY_MPS2 * volume_m3):.0f} m")
    shortest_m = 2 * math.pi * GRAVITY_MPS2 / OMEGAS_RAD_S.max() ** 2
    print(f"largest panel radius {mesh.faces_radiuses.max():.2f} m against an eighth of the shortest wave "
          f"{shortest_m / 8:.2f} m; first irregular frequency without the lid "
          f"{body.first_irregular_frequency_estimate(g=GRAVITY_MPS2):.2f} rad/s")

    # Where the waves go (Capytaine), within (-pi, pi], for where they come from (deckwatch).
    wave_directions_rad = np.radians((180.0 + HEADINGS_DEG + 180.0) % 360.0 - 180.0)
    problems = xr.Dataset(coords={
        "omega": OMEGAS_RAD_S,
        "wave_direction": wave_directions_rad,
        "radiating_dof": DOFS,
        "water_depth": [np.inf],
        "rho": [RHO_KG_M3],
        "g": [GRAVITY_MPS2],
    })
    solver = cpt.BEMSolver()
    data = solver.fill_dataset(problems, body, progress_bar=False)
    solved_s = time.time() - started

    data = data.squeeze(drop=True)
    # Rows the force (influenced dof), columns the motion (radiating dof).
    matrix = lambda name: (data[name].sel(radiating_dof=DOFS, influenced_dof=DOFS)  # noqa: E731
                           .transpose("omega", "influenced_dof", "radiating_dof").values)
    added, damping = matrix("added_mass"), matrix("radiation_damping")
    force = data["excitation_force"].sel(influenced_dof=DOFS, wave_direction=wave_directions_rad)
    force = force.transpose("omega", "wave_direction", "influenced_dof").values
    omegas = data["omega"].values
    assert added.shape == (len(omegas), 6, 6) and force.shape == (len(omegas), len(HEADINGS_DEG), 6)

    # Roll inertia: the IMO code's radius of gyration includes the added inertia at resonance.
    k_roll_m = imo_roll_gyradius_m()
    w_roll = math.sqrt(GRAVITY_MPS2 * GM_M) / k_roll_m
    added_roll = np.interp(w_roll, omegas, added[:, 3, 3])
    total_roll = mass_kg * k_roll_m**2
    inertia = np.diag([
        mass_kg, mass_kg, mass_kg,
        total_roll - added_roll,
        mass_kg * PITCH_GYRADIUS_M**2,
        mass_kg * YAW_GYRADIUS_M**2,
    ])
    critical_roll = 2.0 * math.sqrt(total_roll * c[3, 3])
    radiation_ratio = np.interp(w_roll, omegas, damping[:, 3, 3]) / critical_roll
    viscous_ratio = ROLL_DAMPING_RATIO - radiation_ratio
    viscous = np.zeros((6, 6))
    viscous[3, 3] = viscous_ratio * critical_roll
    print(f"roll: natural {w_roll:.3f} rad/s ({2 * math.pi / w_roll:.2f} s), added inertia "
          f"{added_roll / total_roll:.0%} of the total, dry radius of gyration "
          f"{math.sqrt((total_roll - added_roll) / mass_kg):.2f} m; damping ratio radiation "
          f"{radiation_ratio:.3f} + viscous {viscous_ratio:.3f}")

    # The six coupled equations at each frequency, in Capytaine's exp(-i w t).
    raos = np.empty((len(omegas), len(HEADINGS_DEG), 6), dtype=complex)
    for i, w in enumerate(omegas):
        transfer = -w**2 * (inertia + added[i]) - 1j * w * (damping[i] + viscous) + c
        raos[i] = np.linalg.solve(transfer, force[i].T).T

    # The table: amplitudes per metre of wave (m/m, deg/m), phases as leads (deg).
    heave, roll, pitch = raos[..., 2], np.degrees(1.0) * raos[..., 3], np.degrees(1.0) * raos[..., 4]
    # Roll in head and following seas is nothing (1e-15) by symmetry: its phase, noise, is 0.
    # (Rounded before adding 0.0 so that a lead of -0.04 is written 0.0, not -0.0.)
    lead_deg = lambda z: round(-np.degrees(np.angle(z)), 1) + 0.0 if abs(z) > 1e-9 else 0.0  # noqa: E731
    amplitude = lambda z: f"{abs(z):.4g}" if abs(z) > 1e-9 else "0"  # noqa: E731
    today = datetime.date.today().isoformat()
    with open(args.out, "w") as out:
        out.write(
            f"# The frigate's RAOs (deckwatch-sim ship::Hull::FRIGATE), made by bench/hull_rao.py on {today}\n"
            f"# with Capytaine {cpt.__version__} (boundary elements, zero speed, deep water, lid on the waterplane).\n"
            f"# Hull: y = B/2 (1 - |2x/L|^3) (1 - |z/T|^{section_exponent:.3f}), L {LENGTH_M} m, B {BEAM_M} m, T {DRAFT_M} m; "
            f"{mesh.nb_faces} panels; {mass_kg / 1e3:.0f} t (block {block:.3f}).\n"
            f"# G amidships {OG_M} m above the waterline; GM {hull_gm_m:.3f} m (the hull's own); roll radius of gyration {k_roll_m:.2f} m "
            f"with the added inertia; pitch and yaw {PITCH_GYRADIUS_M} m dry.\n"
            f"# Roll damping at resonance: radiation {radiation_ratio:.3f} of critical + viscous "
            f"{viscous_ratio:.3f} (linear, added) = {ROLL_DAMPING_RATIO}.\n"
            "# heading_deg: where the waves come from off the bow (0 head, 90 from port, 180 following).\n"
            "# Per metre of wave amplitude; phase_deg the lead over the elevation at G: "
            "response = amp a cos(w t + phase) for elevation a cos(w t).\n"
            "# Roll positive raises port, pitch positive lowers the bow, heave G's, up (docs/CONVENTIONS.md §2).\n"
        )
        out.write("omega_rad_s,heading_deg,heave_m_per_m,heave_phase_deg,roll_deg_per_m,roll_phase_deg,"
                  "pitch_deg_per_m,pitch_phase_deg\n")
        for i, w in enumerate(omegas):
            for j, h in enumerate(HEADINGS_DEG):
                out.write(
                    f"{w:.4g},{h:.0f},"
                    f"{amplitude(heave[i, j])},{lead_deg(heave[i, j]):.1f},"
                    f"{amplitude(roll[i, j])},{lead_deg(roll[i, j]):.1f},"
                    f"{amplitude(pitch[i, j])},{lead_deg(pitch[i, j]):.1f}\n"
                )

    beam = list(HEADINGS_DEG).index(90.0)
    peak = int(np.argmax(np.abs(roll[:, beam])))
    print(f"beam seas roll peaks at {omegas[peak]} rad/s ({2 * math.pi / omegas[peak]:.1f} s): "
          f"{abs(roll[peak, beam]):.2f} deg/m")
    print(f"longest waves ({omegas[0]} rad/s): heave head {abs(heave[0, 0]):.3f}, beam {abs(heave[0, beam]):.3f} m/m; "
          f"pitch head {abs(pitch[0, 0]):.3f} deg/m (wave slope {np.degrees(omegas[0]**2 / GRAVITY_MPS2):.3f} deg/m)")
    # The conventions, seen at the longest waves: heave follows the elevation (lead 0), the deck
    # follows the surface's slope: pitch lags it a quarter period in head seas (the surface falls
    # ahead a quarter period before the crest reaches G), roll leads it a quarter in waves from port.
    print(f"longest waves' leads: heave head {lead_deg(heave[0, 0]):.0f} deg, pitch head "
          f"{lead_deg(pitch[0, 0]):.0f} deg (-90 expected), roll from port {lead_deg(roll[0, beam]):.0f} deg (90 expected)")
    print(f"solved in {solved_s:.0f} s; wrote {args.out}")


if __name__ == "__main__":
    main()
