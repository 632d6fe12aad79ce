"""The names a generated kernel receives from its damper model, declared for readers, IDEs and ruff.

The templates (``_kernel_template.py``, ``_driver_template.py``, ``inverse/_onestep_template.py``) import these
names on lines ending in ``# injected``; :func:`~.codegen.render` drops those lines and puts the model's own
definitions above the template instead (its numba functions compiled again inline, so that the Newton loop makes
no calls). Nothing imports this module at run time; the functions are declarations (a docstring, no body) of what the real ones do (see
:class:`~mrd_env.dampers.DamperModel`).
"""
from __future__ import annotations

#: Number of internal states of one damper of the model (``len(model.state_names)``).
ns = 0


def rhs(p, s, x, xd, u, out):
    """ṡ of one damper with parameters p, internal states s, stroke x, velocity ẋ and effective command u, into
    ``out``."""


def force(p, s, x, xd, xdd, u):
    """The damper's force (N)."""


def project(p, s, x, xd, u):
    """Put s back into its invariant set after a step and switch discrete modes, in place."""


def partials(p, s, x, xd, xdd, u, J, work):
    """The Jacobian J (ns + 1, ns + 2) of (ṡ, F) with respect to (s, x, ẋ): the model's analytic derivatives, or
    the kernel's ``fd_partials`` when it has none."""
