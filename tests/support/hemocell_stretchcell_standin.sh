#!/bin/sh
# A stand-in for HemoCell's examples/stretchCell (test HemocellSideBySideDriverWithAStandIn): reads the force from
# config.xml as the example does and writes the example's log, stretch-<F>.log: a first record at rest, then the
# last one with fixed diameters (12.77 and 5.64 um: Mills et al.'s means at 87.6 pN minus and plus 1 um).
F=$(sed -n 's/.*<stretchForce> *\([0-9.]*\).*/\1/p' config.xml)
printf 'iteration axial transverse\n1 7.82 7.82\n40000 12.77 5.64\n' > "stretch-${F%%.*}.log"
