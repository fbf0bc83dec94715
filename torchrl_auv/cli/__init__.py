"""Command-line tools, kept out of the library modules they drive (``python -m
torchrl_auv.cli.<tool> --help``): ``remus100`` (replay a reference run through the 6-DoF
model), ``demonstrations`` (collect scripted-expert demonstrations), ``collection`` (the
data-collection task's card: expert, random and exit policies per preset), ``imitation`` (how
much of the expert's actions a regressor explains), ``local_llm`` (serve the local advisor
model). Each sets the process's thread count and prints; the library modules do neither.
"""
