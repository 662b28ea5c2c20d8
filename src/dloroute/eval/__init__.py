"""Evaluation: benchmark suites as data (``suites``), the parallel resumable runner (``runner``), the paper's
numbers (``paper``) and the markdown report beside them (``report``)."""
