"""A run against ground truth: the evaluator, ground truth, run files, figures,
the analysis of a bag, and the runs it closes (``reproduce``, ``sweep``)."""
