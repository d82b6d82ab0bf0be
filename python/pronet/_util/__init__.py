"""pronet's private helpers: nothing here is API, and any of it may change.

- :mod:`~pronet._util.validate`: array-likes and scalars checked and converted, the
  errors naming the argument;
- :mod:`~pronet._util.files`: atomic files and folders, strict JSON, output checks;
- :mod:`~pronet._util.outputs`: the result folders and progress callbacks the
  experiments share;
- :mod:`~pronet._util.cores`: the cores this process may use;
- :mod:`~pronet._util.extras`: optional dependencies and the one error when missing;
- :mod:`~pronet._util.waiting`: waiting for worker threads without going deaf to signals;
- :mod:`~pronet._util.plausibility`: the physical bounds the API and the readers hold
  data to (gravity, the first IMU step, depth, angles) and the warning of usable data
  that is probably a mistake;
- :mod:`~pronet._util.deprecated`: the deprecated form of :func:`pronet.run_filter`
  (its arrays before streams) turned into the streams it stands for;
- :mod:`~pronet._util.whiteness`: the whiteness test of a stream's innovations
  (:func:`pronet.stats.whiteness`, which re-exports it).

Every subpackage may import from here; nothing here imports the rest of pronet but
:mod:`pronet._core`.
"""

__all__ = [
    "cores",
    "deprecated",
    "extras",
    "files",
    "outputs",
    "plausibility",
    "validate",
    "waiting",
    "whiteness",
]
