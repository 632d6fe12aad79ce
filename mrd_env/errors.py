"""Exceptions raised by simulations."""


class SimulationDivergedError(RuntimeError):
    """A simulation produced a non-finite state or its implicit step could not converge.

    Attributes name the damper ``model``, the simulation ``time`` in s and the batch ``index``.
    """

    def __init__(self, message: str, *, model: str = "", time: float = float("nan"), index: int = -1):
        super().__init__(message)
        self.model = model
        self.time = time
        self.index = index
