"""The array layouts every layer shares: the state, the reference vector, the funnel block, the
paper law's diagnostics.

They are data layouts, not behaviour: the record's columns, the run log's topics, the controllers'
inputs and the references' outputs are laid out by these names, so each is written once here.

- the state ``(x, y, psi, u, v, r)`` [m, m, rad, m/s, m/s, rad/s] (README, Conventions);
- the reference vector ``(x_d, y_d, psi_d, x_d_dot, y_d_dot, r_d, u_d)``: the pose, its time
  derivative and the reference surge speed [m, m, rad, m/s, m/s, rad/s, m/s] (the record's 7
  reference columns, :data:`REF_FIELDS`); the vector a controller receives carries three more
  entries, the reference's accelerations ``(x_d_ddot, y_d_ddot, r_d_dot)`` [m/s^2, m/s^2, rad/s^2]
  (:data:`REF_VECTOR_FIELDS`, :data:`N_REF`): written by every reference, never recorded
  (docs/controllers.md);
- the funnel block (paper Eqs. 9, 14): a controller that tracks in a funnel declares these among
  its diagnostics, and the outputs then show funnel errors and violations;
- the paper's PPC law's diagnostics (Eqs. 8-37), the record's layout when no other is declared.
"""

STATE_FIELDS = ("x", "y", "psi", "u", "v", "r")

REF_FIELDS = ("x_d", "y_d", "psi_d", "x_d_dot", "y_d_dot", "r_d", "u_d")
REF_X, REF_Y, REF_PSI, REF_XDOT, REF_YDOT, REF_R, REF_U = range(len(REF_FIELDS))
#: the vector handed to a controller: the record's 7 entries, then the accelerations (the loops
#: record only the first 7)
REF_VECTOR_FIELDS = REF_FIELDS + ("x_d_ddot", "y_d_ddot", "r_d_dot")
REF_XDDOT, REF_YDDOT, REF_RDOT = range(len(REF_FIELDS), len(REF_VECTOR_FIELDS))
N_REF = len(REF_VECTOR_FIELDS)

FUNNEL_FIELDS = ("e1", "e2", "e3", "rho1", "rho2", "rho3", "z1", "z2", "z3")

# The PPC law's diagnostics vector: tracking errors in the funnel (Eqs. 8-15), then the adaptive
# states (Eqs. 19, 29, 37). Its first 13 entries (TRACKING_FIELDS) are what tracking_errors fills.
DIAG_FIELDS = (
    "e1", "e2", "e3",            # Eq. 14: x_bar - x_bar_d [m], y_bar - y_bar_d [m], wrap(psi - psi_a) [rad]
    "rho1", "rho2", "rho3",      # Eq. 9 bounds
    "z1", "z2", "z3",            # e_i / rho_i
    "e1s", "e2s", "e3s",         # Eq. 10 transformed errors e_i*
    "psi_a",                     # Eq. 15 [rad]
    "u_e", "v_e", "r_e",         # Eq. 19 velocity errors
    "alpha_u", "alpha_v", "alpha_r",  # Eq. 17 virtual controls
    "w_u_norm", "w_v_norm", "w_r_norm",  # |W_u|, |W_v|, |W_r|
    "s2",                        # tanh(gamma_2)
    "s2_clamped",                # 1 when s2 hit its clamp this step
)
