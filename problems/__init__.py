"""The shipped problem files, one mission each, installed as ``esail_opt.problems``.

Each file defines ``problem``. Run one with ``esail-opt solve problems/NAME.py``; from
Python, :func:`esail_opt.optimisation.problem_file.shipped_problem` loads one by name
from whichever installation is imported, with the checks of a problem file given by
path.
"""
