"""The benchmark pipeline behind ``python3 evaluate.py`` (docs/evaluation.md).

Modules, one job each:

* :mod:`.methods` -- the registry of evaluated methods (name -> label, kind, runner) and the
  runners: the AOASS safety stack with or without the policy, the plain spiral, and any
  :class:`~aoass_env.planning.PlannedMethod` (classical paths, reconstructed baselines);
* :mod:`.episode` -- one episode's rows: Eq. 16-19 from the finished simulator, Eq. 15 per
  localizer; the same for a saved beacon log;
* :mod:`.store` -- ``episodes.csv``: schema, crash-safe appending, resume;
* :mod:`.sweep` -- presets, the episode grid, worker processes, progress bar;
* :mod:`.report` -- summary statistics (mean, std, 95 % CI), summary.csv, summary.md and the
  paper's Figures 2-4;
* :mod:`.cli` -- the command line of ``evaluate.py``.
"""
