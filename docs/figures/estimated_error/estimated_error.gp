set terminal pngcairo size 1100,640
set output 'estimated_error.png'
set logscale xy
set grid
set key outside right
set xlabel 'photons'
set ylabel 'relative L1 error of B - E'
set title "reference_round_occluder: estimated bound and true error\nmedian over 10 seeds; default settings but the basis" noenhanced
plot 'estimated_error.dat' index 0 using 1:2 with linespoints lw 2 lc 1 pt 7 title 'constant', 'estimated_error.dat' index 0 using 1:3 with linespoints dt 2 lw 2 lc 1 pt 6 notitle, 'estimated_error.dat' index 1 using 1:2 with linespoints lw 2 lc 2 pt 7 title 'linear', 'estimated_error.dat' index 1 using 1:3 with linespoints dt 2 lw 2 lc 2 pt 6 notitle, 'estimated_error.dat' index 2 using 1:2 with linespoints lw 2 lc 3 pt 7 title 'cubic', 'estimated_error.dat' index 2 using 1:3 with linespoints dt 2 lw 2 lc 3 pt 6 notitle, 'estimated_error.dat' index 3 using 1:2 with linespoints lw 2 lc 4 pt 7 title 'hermite', 'estimated_error.dat' index 3 using 1:3 with linespoints dt 2 lw 2 lc 4 pt 6 notitle, NaN with linespoints lw 2 lc rgb 'gray30' pt 7 title 'true error (solid)', NaN with linespoints dt 2 lw 2 lc rgb 'gray30' pt 6 title 'estimated bound, 95 % (dashed)'
