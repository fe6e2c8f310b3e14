#!/usr/bin/env sh
# LQR control with actuators as the hardware has them, from the shell (docs/simulation.md,
# "Actuators"; docs/analysis.md, "Control design").  Each command writes a folder of results.
set -e

# 1. Shape tracking: shorten the paper's (3,1) shell to 85% of its height and twist it back, an
#    LQR law on the nonlinear model following the quasi-static plan, its commands reaching the
#    tendons through actuators that reel at most 0.2 m/s behind a 5 ms lag.  The summary says
#    whether the targets were reached and whether a limit was (control.json: "saturated").
tensegrity control --height 0.85 --max-rate 0.2 --lag 0.005 --out shape-control

# 2. Regulation under load: an LQR gain at the equilibrium of the 3-bar prism standing on its
#    base (its bottom ring fixed), updated every 5 ms (controller.npz), then a run with 10 N
#    pulling a top node (3) down, the rest lengths held within 1% of their own, changing at
#    most 5 cm/s behind a 10 ms lag: the prism comes to rest under the load. The summary
#    lists the saturations (which tendon, when, how long), the file holds every update's
#    command and applied control.
tensegrity lqr --kind prism --fixed-base --period 0.005 --out prism-lqr
tensegrity simulate --kind prism --fixed-base --controller prism-lqr/controller.npz \
    --rest-range 0.99:1.01 --max-rate 0.05 --lag 0.01 --load 3:0,0,-10 \
    --t-end 2 --no-steady-state --no-view --no-animation --out prism-run
