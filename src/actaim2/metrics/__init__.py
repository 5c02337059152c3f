"""Success-rate statistics shared by training's validation and the evaluation: rates and their
intervals, the Mode SSR, the dependence of outcomes on the mode. numpy only, no other actaim2 layer."""
