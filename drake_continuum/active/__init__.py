"""Active recognition: the observation model, the posterior and Monte-Carlo tree search
that chooses the next wrap, the policies, and training/evaluation on wrap collections."""
