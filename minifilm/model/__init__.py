"""The paper's networks (Omega, Phi, Psi) and losses, built from minifilm.nn."""
