#!/bin/sh
# A stand-in for HemoCell's examples/oneCellShear (test HemocellShearDriverWithAStandIn): writes the example's
# record, stretch.log (iteration, bounding box x y z um, volume %, area %, largest diameter um, deformation index
# %), every 20000 iterations of 5e-8 s (1 ms) to 5 ms: the box's z side (the velocity gradient) 2.29 + 0.01 um per
# ms, the others 7.82 um.
i=1
for z in 2.30 2.31 2.32 2.33 2.34; do
  printf '%d 7.82 7.82 %s 100 100 7.82 0\n' $((i * 20000)) "$z"
  i=$((i + 1))
done > stretch.log
