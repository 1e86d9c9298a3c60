"""DPD <-> physical unit conversions: the single source of every conversion factor (docs/physics.md section 1).

Conventions follow the Mirheo set-up that produced the published training data:

* length unit  u_l = cutoff r_c = 0.25 um (so a bubble of diameter D um has DPD radius D/0.5);
* energy unit  u_e = k_B T at T = 300 K (k_B = 1.3805e-23 J/K, the value of Mirheo's parameter file);
* mass unit    u_m = rho_water u_l^3 / 3 (a water bead has mass 1 at number density 3);
* time unit    u_t = sqrt(u_m u_l^2 / u_e).

**Water density.** The default rho_water = 997 kg/m^3 is the value of the simulation parameter file
(``parameters-default.emb.yaml``) from which every other DPD constant of the published set-up was derived,
giving u_t = 8.852 us (1/u_t = 0.11296 MHz). The published PCA frequency table used rho = 1000 kg/m^3
(u_t = 8.866 us); ``UnitSystem(rho_water=1000.0)`` reproduces those numbers exactly (docs/decisions.md).

**Force scale.** Shell quantities carry the factor ``fscale`` = 0.0074 between experiment and
simulation: a physical force F [N] is F_dpd = fscale F / (u_e/u_l), so 1 nN = 446.698 DPD force.
The same factor applies to everything measured on the shell (force, stiffness = force/length,
2-D moduli k_a and mu, bending modulus k_b, Young's modulus).  It does not apply to time,
frequency, length, or to the solvent's thermodynamic pressure (units u_e/u_l^3 = 0.265 Pa).

**Moduli.** With shell thickness h = 5 nm and Poisson ratio nu = 1/2:
k_a = fscale E h / (2(1-nu)) / (u_e/u_l^2);  mu = fscale E h / (2(1+nu)) / (u_e/u_l^2) = k_a/3;
k_b = fscale (2/sqrt 3) E h^3 / (12 (1-nu^2)) / u_e  (2/sqrt 3: Kantor discretisation on a
triangulated sphere).  So E = 10 MPa <-> k_a = 5,584 and the published sampling variable
Yt [Pa] = 1790.92 k_a (= E at nu = 1/2).

**Ringdown mass scale.** Ringdown runs multiply the shell mass by ``mass_factor`` (160 in the
published sweeps); a frequency measured in such a run is converted with f = f_dpd sqrt(M)/u_t.

Units of the parameters (their names are defined in :mod:`bubblecal.data.names`): ``ka`` (stretching
modulus, DPD 2-D modulus), ``kb`` (bending, DPD energy), ``b1, b2, a3, a4`` (dimensionless Lim
coefficients), ``d0`` (contact/indentation offset, DPD length), ``sigma``, ``sigma_mech``, ``sigma_ac``
(dimensionless relative noise amplitudes).

Every conversion method of :class:`UnitSystem` takes a float or array_like and returns float64 values
(a NumPy array, or a NumPy scalar for a scalar input).
"""

from bubblecal.data.units.system import DEFAULT_UNITS, K_BOLTZMANN, UnitSystem, radius_dpd_from_diameter_um

__all__ = ["K_BOLTZMANN", "UnitSystem", "DEFAULT_UNITS", "radius_dpd_from_diameter_um"]
