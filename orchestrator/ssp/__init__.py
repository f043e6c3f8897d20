"""SSP 1.0 (System Structure and Parameterization): the plant exported for other masters
(export.py) and a plant or role read from another tool's SSP archive (read.py)."""
