# The validation's config helpers, sourced by run.sh and explore_inertial.sh (which set $configs to
# apps/triaxial/configs).
# narrow FILE P0 B: FILE's campaign cut to one constant-p test (p0 P0 Pa, b B), one at a time.
narrow() { sed "s/^p0 = .*/p0 = [$2]/; s/^path = .*/path = [\"constant_p\"]/; s/^b = .*/b = [$3]/; s/^parallel = .*/parallel = 1/" "$1"; }
# seeded NAME SEED: the shipped config NAME.toml with sample.seed = SEED.
seeded() { sed "s/^seed = .*/seed = $2/" "$configs/$1.toml"; }
