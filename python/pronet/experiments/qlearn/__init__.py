"""Learning Q from missions with ground truth (docs/how-to/learning-q.md, "Learning from
recorded missions"): the sections, the core's scores, training through the
differentiable filter and the honest evaluation.

- :mod:`~pronet.experiments.qlearn.sections`: recorded sections with ground truth and
  simulated ``regimes`` recordings with their true q, as one section type;
- :mod:`~pronet.experiments.qlearn.scoring`: a q schedule scored on the core, the
  constant row scaled over a grid, the per-section best constant, paired tables;
- :mod:`~pronet.experiments.qlearn.protocol`: leave-one-section-out, held-out splits,
  the ledger of scored (model, test set) pairs, model (a)'s fit;
- :mod:`~pronet.experiments.qlearn.gradient`: the Kalman-informed loss through the torch
  filter and model (b)'s training (the windowed CNN);
- :mod:`~pronet.experiments.qlearn.akit_training`: model (c)'s training (the A-KIT-like
  model, :mod:`pronet.learn.akit`), the filter run chunk by chunk;
- :mod:`~pronet.experiments.qlearn.commands`: what ``pronet train --recorded`` and
  ``--simulated`` run.

The models themselves live in :mod:`pronet.learn` (:mod:`~pronet.learn.qmodels`,
:mod:`~pronet.learn.akit`), where ``learned:PATH`` loads them.
"""

__all__ = ["akit_training", "commands", "gradient", "protocol", "scoring", "sections"]
