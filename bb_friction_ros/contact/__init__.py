"""Contact mechanics: Hertz ellipses and Coulomb friction maps over them (paper Appendix)."""
