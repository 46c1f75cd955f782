set terminal pngcairo size 960,600 font 'DejaVu Sans,11'
set output 'speed-vs-error.png'
set title 'Time per update against RMS marker error, all scenes'
set logscale xy
set xlabel 'time per update (µs)'
set ylabel 'RMS marker error (relative)'
set key outside right top
set grid
plot for [i=0:11] 'speed-vs-error.dat' index i using 1:2 title columnheader(1) with points pointsize 1.3
