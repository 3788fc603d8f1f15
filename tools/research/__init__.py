"""The paper's research code: ES tuning (``tune_es``), the paper's experiments (``paper_table``, ``make paper``),
gain-schedule plots and the experiment library they share (``experiments/``). Not shipped in the wheel: run it
from a repository checkout."""
