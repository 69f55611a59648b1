"""
The servo test: the product's feedforward judged in closed loop (docs/servo_test.md).

A simulated axis (``plant``: the product's model as its friction, stick at standstill) under
the common cascade (``controller``), following a recorded or generated reference
(``reference``), with each friction feedforward (``modes``, ``baselines``) in the same run;
``run`` steps them, ``metrics`` reads the figures off, ``outputs`` writes them, ``workflow``
does it all, ``cli`` registers ``bb-friction servo-test``.
"""
