"""The study's published numbers (docs/physics.md section 7) and the criteria by which
`triaxial analyze` calls them reproduced."""


STUDY = {
    "e_gamma": 0.699, "lambda": 0.0002, "xi": 0.971, "R": 0.96,
    "phi_deg": 22.0, "d0": 0.619, "m": 4.570,
}


CRIT = {
    "e_abs": 0.01,         # e_Gamma: within 0.01 of 0.699 (a void ratio: absolute; the study's CSL drops 0.026
                           # over 0.5-16 MPa, so 10 % of e_Gamma, 0.07, would pass any sand's line)
    "csl_rel": 0.10,       # CSL lambda, xi: within 2 SE or 10 % of the study's value
    "csl_curve": 0.01,     # CSL curve: |e_c - e_c,study| <= 0.01 over the tested p range
    "R_min": 0.92,         # fit quality: R >= 0.96 - 0.04
    "phi_tol_deg": 2.0,    # friction angle within 2 degrees of 22
    "dil_rel": 0.15,       # d0, m: within 2 SE or 15 %
    "rho": 0.8,            # trend: Spearman rho beyond +-0.8 in every (path, p0) group
    "csl_unique": 0.005,   # |mean CSL residual| of every b <= 0.005 (the e tolerance)
    "aic_margin": 2.0,     # M(theta) surfaces: one is preferred when the next AICc is >= 2 above it
}
