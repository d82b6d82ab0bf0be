"""The noise regressors and how they are made: a window of raw IMU samples in, its
per-sample noise variance q out.

- :mod:`~pronet.learn.windowstats`: window statistics in NumPy (the detrended variance,
  the Cramér–Rao floor, the handcrafted features);
- :mod:`~pronet.learn.models`: the regressors (the ProNet CNNs in torch, the HCF
  ensemble, the detrended variance), :func:`~pronet.learn.models.load` by name or path;
- :mod:`~pronet.learn.hcf`: the handcrafted-feature ensemble as plain arrays;
- :mod:`~pronet.learn.frozen`: trained regressors frozen in pronet's core, run without
  torch;
- :mod:`~pronet.learn.modelfile`: model files (safetensors weights and a JSON card) and
  the shipped ones (``weights/``);
- :mod:`~pronet.learn.dataset`: the ProNet training set of labelled IMU windows;
- :mod:`~pronet.learn.training`: training and scoring the regressors;
- :mod:`~pronet.learn.hybrid`: the ProNet hybrid loop, a regressor setting the process
  noise of running filters;
- :mod:`~pronet.learn.qmodels`: Q models learned from recorded missions (the section
  scale; :func:`~pronet.learn.qmodels.load_model_file` opens any model file);
- :mod:`~pronet.learn.akit`: the A-KIT-like Q model that also reads the filter's
  velocity (its training: :mod:`pronet.experiments.qlearn`);
- :mod:`~pronet.learn.torchfilter`: the differentiable filter in torch.

Training needs the ``torch`` extra; loading a shipped model does not.
"""

__all__ = [
    "akit",
    "dataset",
    "frozen",
    "hcf",
    "hybrid",
    "modelfile",
    "models",
    "qmodels",
    "torchfilter",
    "training",
    "windowstats",
]
