"""A small sample for the path examples: spheres of 5-7.5 mm (soft quartz, E = 7 GPa, so the step is
long), compressed isotropically to p0 with the given friction (with friction: loose; without:
dense), strains counted from there."""
import sandcell as sc


def prepare(count=500, p0=1e5, friction=0.5, seed=1, threads=2):
    mat = sc.Material(young=7e9)
    contact = sc.ContactSettings()
    contact.skin, contact.sort_interval = 0.5e-3, 1000
    t_r = sc.rayleigh_time(2.5e-3, mat)
    prep = sc.Model(0.2 * t_r, [sc.Material(young=7e9, friction=friction)], contact)
    s = prep.servo
    s.enabled, s.path, s.control, s.p, s.max_rate = True, "isotropic", ["stress"] * 3, p0, 5.0
    s.gain = sc.derived_servo("prepare", p0, mat, 0.2 * t_r)[0]
    world = sc.World(prep, sc.State.generate(prep, count, 5e-3, 7.5e-3, seed=seed), threads=threads)
    while True:
        world.step(1000)
        m = world.measure()
        if max(abs(m.stress[k, k] - p0) / p0 for k in range(3)) < 0.01 and m.unbalanced < 0.01:
            break
    state = world.state()
    state.cell_length0 = state.cell_length
    state.reset_clock()
    state.cell_rate = [0, 0, 0]
    model = sc.Model(0.2 * t_r, [mat], contact)  # shearing: the material's own friction
    return model, state, m
