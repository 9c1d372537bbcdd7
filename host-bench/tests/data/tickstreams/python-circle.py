import csv, math
R, v, b, step, dt = 0.5, 0.2, 0.2, 0.01, 0.1     # circle radius m, speed m/s, wheel spacing m, m per count, truth period s
w = v / R                                        # turn rate, rad/s (counter-clockwise)
T = 2 * math.pi / w                              # one lap, s
rows = []
for enc, speed in ((0, v - w * b / 2), (1, v + w * b / 2)):  # encoder 0 = left wheel, 1 = right wheel
    rows += [(round(k * step / speed * 1e9), "tick", enc, 1, "", "", "") for k in range(1, int(speed * T / step) + 1)]
rows += [(round(i * dt * 1e9), "truth", "", "", R * math.sin(w * i * dt), R - R * math.cos(w * i * dt), w * i * dt)
         for i in range(int(T / dt) + 1)]        # starts at (0, 0) heading +x; circle centre (0, R)
rows.sort(key=lambda r: r[0])
with open("python-circle.csv", "w", newline="") as f:
    f.write("# omnibench tick stream v1\r\n# robot: diff-drive.toml\r\n")
    out = csv.writer(f)
    out.writerow(["t_ns", "kind", "id", "value", "x_m", "y_m", "theta_rad"])
    out.writerows(rows)
