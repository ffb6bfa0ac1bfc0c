"""The schedulers, one subpackage per method of ``docs/design/milp.md``, and the parts they share.

* :mod:`.greedy`: the greedy scheduler, the baseline and every portfolio's
  start (no model: the checker's rules);
* :mod:`.blocks`: the paper's method, prune, the block-division MILP
  (B0-B11, section 1), a shortest path inside each block;
* :mod:`.slots`: the fixed-grid slot-assignment MILP (S0-S3, section 2),
  its grid (G1-G3) and the exposure menu;
* :mod:`.bounds`: certified upper bounds on the coverage of any plan
  (U0-U4, V1-V7, sections 3 and 4);
* :mod:`.detection`: the detection objective on the slot model (X1-X10 of
  ``docs/design/detection.md``);
* :mod:`.portfolio`: the hybrid portfolio, the continuous-time model
  (C0-C6, section 5) and its large-neighbourhood search (H1-H5, section 6);
* :mod:`.milp`: the MILP adapter every model uses, rows named after their
  equations, HiGHS and Gurobi.

Shared by the methods and the planner (the modules here): :mod:`.gain` (the
least-gain rule), :mod:`.as_executed` (a plan's coverage as ZTF's scheduler
executes its queues, Q14 of ``docs/design/executed.md``) and
:mod:`.completions` (a re-plan's completions of half-done pairs, P3-P7 of
``docs/design/replan.md``).  The slew times every method plans with are the
telescope's (:mod:`..telescope.slew`).

The rooms form a stack (``tests/test_architecture.py``): :mod:`.milp` at the
bottom, the portfolio on top; a method uses only the ones below it.
"""
