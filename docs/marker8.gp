set terminal pngcairo size 960,600 font 'DejaVu Sans,11'
set output 'marker8.png'
set title 'Marker 8 during the arm ramp to 2.07 N·m (ramp 1 s, hold 2 s)'
set xlabel 'time (s)'
set ylabel 'displacement (mm)'
set key outside right top
set grid
plot for [i=0:5] 'marker8.dat' index i using 1:2 title columnheader(1) with lines linewidth 2
