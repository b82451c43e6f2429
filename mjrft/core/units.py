"""Named unit conversions. Everything inside mjrft is SI; convert only at the boundary."""

#: 1 N/cm^3 expressed in N/m^3 (published RFT coefficients are usually given in N/cm^3).
N_PER_CM3 = 1.0e6
#: 1 cm in m.
CM = 1.0e-2
#: 1 mm in m.
MM = 1.0e-3
#: 1 degree in rad.
DEG = 3.141592653589793 / 180.0
