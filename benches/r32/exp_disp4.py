"""exp_disp3's estimators with the gray edge taken on J smoothed by a 5 x 5
box (the core's, METHOD §13.4) instead of a Gaussian of 2 px."""
import displab as D
from exp_disp3 import candidates

if __name__ == "__main__":
    D.run(candidates, edge_fn=D.box_edges)
