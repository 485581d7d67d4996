"""Step-to-step thrust control with certified contact (SPEC 11): the affine step model,
the per-step QP and the closed loop on the full-order simulation."""
