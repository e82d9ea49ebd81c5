"""Reference implementations: slower, literal versions of the paper's algorithms and simpler solver
paths, kept to check the fast production solvers against (tests/) and for readers who want the
paper's Algorithm 1 as printed. Not used by the pipeline."""
