"""The acquisition's sizes in plain Python: the largest rig (photograph side, cameras, lights,
shots) and the per-texel fit's default steps.

``hbrdf acquire``'s parser bounds its flags by them and states them in its help, and a command
line's parser imports no NumPy (issue 57); :mod:`~hybridbrdf.acquire.rig` and
:mod:`~hybridbrdf.acquire.acquisition`, which use them, do."""

#: Largest photograph side, and most cameras, lights and shots in one rig.
MAX_SIDE = 8192
MAX_ITEMS = 65536

#: Steps of the per-texel stage by default (the analytic stage runs half as many).
STEPS = 300
