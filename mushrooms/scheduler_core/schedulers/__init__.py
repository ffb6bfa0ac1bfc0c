"""The schedulers: greedy, the slot-assignment MILP, the MUSHROOMS block method, and their parts.

Parts: pruning to a shortlist, the least-gain rule, slew times and
within-block ordering, the backend-neutral MILP adapter, and the certified
upper bound on coverage.
"""
