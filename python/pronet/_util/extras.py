"""Optional dependencies: what needs them, and the one error when they are missing.

``pip install pronet`` brings what the native strategies, recorded data, sweeps, the
shipped models (frozen in the core), the detrended variance, plots and tables need.
Training and running the nets through torch need torch, training the HCF ensemble
needs scikit-learn: both come with ``pip install 'pronet[torch]'``. Reading ROS bags
(``pronet real --format bag``) needs rosbags: ``pip install 'pronet[rosbags]'``.
"""

from __future__ import annotations

#: The extra that installs each optional module.
EXTRAS = {"torch": "torch", "sklearn": "torch", "rosbags": "rosbags"}


class MissingExtra(ImportError):
    """An optional dependency is not installed; the message names what needs it and the
    extra that installs it."""


def missing(module: str, what: str) -> MissingExtra:
    """The error for ``module`` (one of :data:`EXTRAS`) not being installed: ``what``
    needs it, and the extra that installs it."""
    return MissingExtra(
        f"{what} needs {module}, which is not installed: pip install 'pronet[{EXTRAS[module]}]'",
        name=module,
    )
