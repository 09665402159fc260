"""rotorlab: a virtual rotorcraft lab.

Sub-packages: ``rotorlab.vehicles`` (digital twins), ``rotorlab.scenes`` (rigs, thrust stand, free
flight), ``rotorlab.sim`` (physics stepping, flight software, scenarios, logs), ``rotorlab.ident``
(system identification), ``rotorlab.tune`` (structured H-inf tuning and robustness).

Importing this package stays light: nothing here imports MuJoCo, so ``rotorlab.ident`` and
``rotorlab.tune`` can be used on flight logs without a simulator.
"""

__version__ = "0.1.0"
