"""
Discrepancy workflow: where and why measured friction differs from the model.

``bb-friction discrepancy BAG_OR_CSV --out DIR`` runs the model over a recording (the replay
path), locates the residual (``regimes``), selects physically named empirical terms that
explain it (``bb_friction_ros.empirical_terms``, ``selection``), writes them into
``DIR/augmented.yaml`` and shows the gap shrink on held-out data (``report``).
See docs/discrepancy.md.
"""
