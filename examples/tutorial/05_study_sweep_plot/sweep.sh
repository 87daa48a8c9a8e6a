# The same study from the shell: a table of mean A_w per cell, and every run in loss-study/.
ayllu sim sweep examples/tutorial/05_study_sweep_plot/loss.toml --out "$OUT/loss-study"
head -3 "$OUT/loss-study/runs.csv"
