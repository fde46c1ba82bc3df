# Writes fuzz/seeds/geotiff/cog-deflate-predictor.tif:
#   python3 scripts/cog-seed.py fuzz/seeds/geotiff/cog-deflate-predictor.tif
# A COG writer independent of hitex's own (pure Python, zlib): an int16 DEM,
# deflate tiles with horizontal differencing (predictor 2), laid out as GDAL
# lays a COG out (IFDs first, tiles coarsest first), overviews by 2x2 means,
# GDAL_NODATA, geographic EPSG:4326, PixelIsPoint.
import struct, zlib, math, sys
W, H, T = 200, 150, 64
step = 1/3600.0
lon0, lat0 = -35.2, -7.8
def z(i, j):
    x, y = i / W - 0.5, j / H - 0.5
    return 40 + 300 * math.exp(-(x*x + y*y) * 9) + 60 * math.sin(x * 30) * math.cos(y * 22)
full = [[int(round(z(i, j))) for i in range(W)] for j in range(H)]
for j in range(70, 73):
    for i in range(80, 86):
        full[j][i] = -32768
levels = [full]
while len(levels[-1][0]) > T or len(levels[-1]) > T:
    a = levels[-1]; h, w = len(a), len(a[0])
    nh, nw = (h + 1) // 2, (w + 1) // 2
    b = []
    for j in range(nh):
        row = []
        for i in range(nw):
            v = [a[y][x] for y in (2*j, 2*j+1) if y < h for x in (2*i, 2*i+1) if x < w and a[y][x] != -32768]
            row.append(int(round(sum(v) / len(v))) if v else -32768)
        b.append(row)
    levels.append(b)
def tiles(a):
    h, w = len(a), len(a[0]); out = []
    for ty in range(0, h, T):
        for tx in range(0, w, T):
            raw = bytearray()
            for y in range(ty, ty + T):
                prev = 0
                for x in range(tx, tx + T):
                    v = a[y][x] if (y < h and x < w) else 0
                    d = (v - prev) & 0xffff; prev = v
                    raw += struct.pack('<H', d)
            out.append(zlib.compress(bytes(raw), 6))
    return out
enc = [tiles(a) for a in levels]
def entry(tag, typ, vals):
    fmt = {3: 'H', 4: 'I', 12: 'd', 2: 's'}[typ]
    if typ == 2:
        data = vals.encode() + b'\0'; count = len(data)
    else:
        data = struct.pack('<%d%s' % (len(vals), fmt), *vals); count = len(vals)
    return (tag, typ, count, data)
ifds = []
for k, a in enumerate(levels):
    h, w = len(a), len(a[0]); n = len(enc[k])
    e = [entry(254, 4, [1 if k else 0]), entry(256, 4, [w]), entry(257, 4, [h]), entry(258, 3, [16]),
         entry(259, 3, [8]), entry(262, 3, [1]), entry(277, 3, [1]), entry(284, 3, [1]), entry(317, 3, [2]),
         entry(322, 3, [T]), entry(323, 3, [T]), entry(324, 4, [0]*n), entry(325, 4, [len(t) for t in enc[k]]),
         entry(339, 3, [2])]
    if k == 0:
        e += [entry(33550, 12, [step, step, 0.0]), entry(33922, 12, [0, 0, 0, lon0, lat0, 0]),
              entry(34735, 3, [1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 2, 2048, 0, 1, 4326]),
              entry(42113, 2, "-32768")]
    ifds.append(e)
# lay out: header, IFDs with their values, then tile data coarsest first
buf = bytearray(b'II*\0' + struct.pack('<I', 8))
tile_off_pos = []
for k, e in enumerate(ifds):
    start = len(buf)
    if k: struct.pack_into('<I', buf, next_pos, start)
    else: struct.pack_into('<I', buf, 4, start)
    extra = start + 2 + 12 * len(e) + 4
    vals = bytearray(); body = bytearray(struct.pack('<H', len(e)))
    for tag, typ, count, data in e:
        body += struct.pack('<HHI', tag, typ, count)
        if len(data) <= 4:
            pos = start + len(body); body += data.ljust(4, b'\0')
        else:
            pos = extra + len(vals); body += struct.pack('<I', pos); vals += data
            if len(vals) % 2: vals += b'\0'
        if tag == 324: tile_off_pos.append(pos)
    next_pos = start + len(body)
    body += struct.pack('<I', 0)
    buf += body + vals
for k in reversed(range(len(levels))):
    for t, data in enumerate(enc[k]):
        struct.pack_into('<I', buf, tile_off_pos[k] + 4 * t, len(buf))
        buf += data
open(sys.argv[1], 'wb').write(buf)
print([(len(a[0]), len(a)) for a in levels], len(buf), 'bytes')
