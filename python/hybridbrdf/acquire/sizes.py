"""The acquisition's sizes in plain Python: the largest rig (photograph side, cameras, lights,
shots), the per-texel fit's default steps and the network fine-tune's.

``hbrdf acquire``'s parser bounds its flags by them and states them in its help, and a command
line's parser imports no NumPy (issue 57); :mod:`~hybridbrdf.acquire.rig` and
:mod:`~hybridbrdf.acquire.acquisition`, which use them, do."""

#: Largest photograph side, and most cameras, lights and shots in one rig.
MAX_SIDE = 8192
MAX_ITEMS = 65536

#: Steps of the per-texel stage by default (the analytic stage runs half as many).
STEPS = 300

#: The network fine-tune by default: FINETUNE_STEPS steps when the capture has at least
#: FINETUNE_MIN_SHOTS photographs, none below (docs/ACQUISITION_GAP.md, "The fine-tune anchored
#: where no photograph looked": from 32 photographs on it was lower than the frozen fit in 17 of
#: 20 cells and tied or beat it in step 1's verdict; at 8 it was worse).
FINETUNE_STEPS, FINETUNE_MIN_SHOTS = 200, 32


def default_finetune(shots: int) -> int:
    """The network fine-tune's steps for a capture of ``shots`` photographs when none are asked for."""
    return FINETUNE_STEPS if shots >= FINETUNE_MIN_SHOTS else 0
