"""What the fitted model leaves: the residual's noise model (AR spectrum, restricted
likelihood over segments) and its verdict, sensor noise or model error."""
