"""Evaluation of the policy and the baselines in simulation (``actaim2 evaluate``, docs/evaluation.md).

  evalset       the fixed objects and seeds (seeds disjoint from data collection's)
  methods       the table rows (ActAIM2, baselines) and how their samples are grouped
  tasks         one task = one executed sample; keys, plan, sample counts
  presets       --smoke / --quick / full sizes
  sim_views     views of the simulated scene made as training made them
  sources       where each method's keyposes come from (policy, Goal-RVT oracle, samplers)
  episode       one sample: reset, keyposes, execution as in data collection, outcome
  outcome       success and (DoF, direction) of an executed sample
  worker        a process's simulator, planner and sources
  results       resumable JSONL of records, run identity
  tables        the markdown tables (paper Table 1, Table 2, appendix, acceptance checks)
  checkpoints   a checkpoint's perception configuration and digests
  evaluate_cli  the command
  standin       the three-drawer stand-in of the fine-tuning result: its episodes, verdicts and tables
  standin_cli   its command, ``actaim2 eval-standin``
"""
