"""The evaluation protocol: the lock that freezes a recipe before a test split is run, the ledger of
every run on a test split, and the options evaluate and validate share to honour them. Below
training and evaluation, which both guard the test splits with it."""
