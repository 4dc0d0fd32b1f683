// AnchoredAsset.cs -- reads the one anchored splat primitive of a GLB
// (KHR_gaussian_splatting + GSVERSE_gaussian_splatting_mesh_anchor, spec v1.2), refuses what
// the spec makes invalid (AnchorRefusedException), dequantizes, expands faceCounts, derives
// compact local anchors and computes the local profile's rest quantities, all in double, once
// per asset. The steps and their order are those of
// gsverse_format/conformance/minimal_reader.py and native/gsverse_remap.h.
using System;
using System.Collections.Generic;

namespace Gsverse.MeshAnchor
{
    public sealed class AnchoredAsset
    {
        public const string Khr = "KHR_gaussian_splatting";
        public const string Anchor = "GSVERSE_gaussian_splatting_mesh_anchor";
        const double EpsDegenerate = 1e-6;   // spec Triangle frames (the rest classification)

        public bool Games, Rigid;
        public int Count, FaceCount, ShCoefficients;
        public float[] AnchorVertices;   // rest anchor mesh, 3V
        public uint[] Indices;           // 3F
        public uint[] Face;              // N
        public float[] Bary;             // 2N
        public float[] Offset;           // N: normalOffset (local) or rho (games)
        public float[] Rotation;         // 4N: localRotation, normalized (local)
        public float[] Scale;            // 3N: localScale (local)
        public RestFace[] Rest;          // F (local)
        public float[] RestMeans, RestRotation, RestScale, Opacity, Sh;   // rest pose; Sh N*K*3

        static readonly string[] Derived = { "barycentrics", "normalOffset", "localRotation", "localScale" };

        public static AnchoredAsset Read(byte[] glb)
        {
            var d = new Glb(glb);
            var asset = new AnchoredAsset();
            asset.Load(d);
            return asset;
        }

        static Dictionary<string, object> Ext(Dictionary<string, object> o, string name)
        {
            return Glb.Obj(Glb.Get(Glb.Obj(Glb.Get(o, "extensions")), name));
        }

        static void FindPrimitive(Glb d, out Dictionary<string, object> prim, out Dictionary<string, object> ext)
        {
            prim = null;
            ext = null;
            int found = 0;
            var meshes = Glb.List(d.Doc, "meshes");
            for (int m = 0; m < meshes.Count; ++m)
                foreach (object p in Glb.List(Glb.Obj(meshes[m]), "primitives"))
                {
                    var khr = Ext(Glb.Obj(p), Khr);
                    var khrExtensions = Glb.Obj(Glb.Get(khr, "extensions"));
                    if (khrExtensions == null || !khrExtensions.ContainsKey(Anchor)) continue;
                    long mode = Glb.IntOr(Glb.Obj(p), "mode", 4);
                    if (mode != 0)
                        throw new AnchorRefusedException("the anchored splat primitive of mesh " + m + " has mode " + mode + ", not POINTS (0)");
                    found++;
                    prim = Glb.Obj(p);
                    ext = Glb.Obj(khrExtensions[Anchor]);
                    if (ext == null) throw new AnchorRefusedException("anchor extension must be an object");
                }
            if (found != 1) throw new AnchorRefusedException("expected one anchored splat primitive, found " + found);
        }

        static bool AllFinite(float[] values)
        {
            foreach (float v in values) if (float.IsNaN(v) || float.IsInfinity(v)) return false;
            return true;
        }

        /// <summary>The spec's allowed accessor layouts (§Accessor component types).</summary>
        public static bool Allowed(string prop, Accessor a)
        {
            int ct = a.ComponentType;
            bool nz = a.Normalized, u = ct == ComponentType.UnsignedByte || ct == ComponentType.UnsignedShort;
            switch (prop)
            {
                case "faceIndex":
                case "faceCounts": return a.Type == "SCALAR" && !nz && (u || ct == ComponentType.UnsignedInt);
                case "barycentrics": return a.Type == "VEC2" && ((ct == ComponentType.Float && !nz) || (nz && u));
                case "normalOffset":
                case "rho": return a.Type == "SCALAR" && ct == ComponentType.Float && !nz;
                case "localRotation":
                    return a.Type == "VEC4" && ((ct == ComponentType.Float && !nz)
                                                || (nz && (ct == ComponentType.Byte || ct == ComponentType.Short)));
                case "localScale": return a.Type == "VEC3" && ((ct == ComponentType.Float && !nz) || u);
                default: return false;
            }
        }

        void Load(Glb d)
        {
            Dictionary<string, object> prim, ext;
            FindPrimitive(d, out prim, out ext);
            var attrs = Glb.Obj(Glb.Get(prim, "attributes")) ?? new Dictionary<string, object>();
            foreach (string name in new[] { "POSITION", Khr + ":ROTATION", Khr + ":SCALE", Khr + ":OPACITY", Khr + ":SH_DEGREE_0_COEF_0" })
                if (!attrs.ContainsKey(name)) throw new AnchorRefusedException("splat primitive lacks " + name);
            Accessor positions = d.Accessor(attrs["POSITION"], "POSITION", "VEC3");
            if (positions.ComponentType != ComponentType.Float) throw new AnchorRefusedException("POSITION must be FLOAT");
            int n = Count = positions.Count;
            Accessor rotations = d.Accessor(attrs[Khr + ":ROTATION"], "ROTATION", "VEC4");
            Accessor scales = d.Accessor(attrs[Khr + ":SCALE"], "SCALE", "VEC3");
            Accessor opacities = d.Accessor(attrs[Khr + ":OPACITY"], "OPACITY", "SCALAR");
            var sh = new List<Accessor>();
            for (int level = 0; level < 4; ++level)
            {
                var names = new List<string>();
                for (int c = 0; c < 2 * level + 1; ++c) names.Add(Khr + ":SH_DEGREE_" + level + "_COEF_" + c);
                if (!names.TrueForAll(attrs.ContainsKey)) break;
                foreach (string nm in names) sh.Add(d.Accessor(attrs[nm], nm, "VEC3"));
            }
            var counted = new List<Accessor> { rotations, scales, opacities };
            counted.AddRange(sh);
            foreach (Accessor a in counted)
                if (a.Count != n) throw new AnchorRefusedException("a splat attribute's count differs from POSITION count");
            RestMeans = positions.Floats();
            RestRotation = rotations.Floats();
            RestScale = scales.Floats();
            if (!AllFinite(RestMeans) || !AllFinite(RestRotation) || !AllFinite(RestScale))
                throw new AnchorRefusedException("non-finite rest pose (POSITION, ROTATION or SCALE)");
            Opacity = opacities.Floats();
            ShCoefficients = sh.Count;
            Sh = new float[n * sh.Count * 3];
            for (int k = 0; k < sh.Count; ++k)
            {
                float[] coef = sh[k].Floats();
                for (int i = 0; i < n; ++i)
                    for (int j = 0; j < 3; ++j) Sh[(i * sh.Count + k) * 3 + j] = coef[3 * i + j];
            }

            // the anchor mesh: at most one node instantiates it, TRIANGLES, FLOAT positions
            object meshIndex = Glb.Get(ext, "mesh");
            var mesh = d.Item("meshes", meshIndex, "anchor mesh");
            int users = 0;
            foreach (object node in Glb.List(d.Doc, "nodes"))
            {
                long? m = Glb.Int(Glb.Get(Glb.Obj(node), "mesh"));
                if (m != null && m == Glb.Int(meshIndex)) users++;
            }
            if (users > 1) throw new AnchorRefusedException("the anchor mesh is instantiated by " + users + " nodes; at most one is allowed");
            var aprims = Glb.List(mesh, "primitives");
            long? p = Glb.Int(Glb.Get(ext, "primitive") ?? 0.0);
            if (p == null || p < 0 || p >= aprims.Count) throw new AnchorRefusedException("anchor primitive index out of range");
            var aprim = Glb.Obj(aprims[(int)p]) ?? new Dictionary<string, object>();
            if (Glb.IntOr(aprim, "mode", 4) != 4) throw new AnchorRefusedException("anchor primitive mode is not TRIANGLES (4)");
            var aattrs = Glb.Obj(Glb.Get(aprim, "attributes"));
            if (aattrs == null || !aattrs.ContainsKey("POSITION")) throw new AnchorRefusedException("anchor primitive has no POSITION");
            Accessor apos = d.Accessor(aattrs["POSITION"], "anchor POSITION", "VEC3");
            if (apos.ComponentType != ComponentType.Float || apos.Normalized)
                throw new AnchorRefusedException("anchor POSITION must be FLOAT");
            AnchorVertices = apos.Floats();
            int nv = apos.Count;
            if (aprim.ContainsKey("indices"))
            {
                Accessor idx = d.Accessor(aprim["indices"], "anchor indices", "SCALAR");
                if (idx.ComponentType == ComponentType.Float || idx.ComponentType == ComponentType.Byte
                    || idx.ComponentType == ComponentType.Short || idx.Normalized)
                    throw new AnchorRefusedException("anchor indices must be unsigned integers, not normalized");
                Indices = idx.UInts();
            }
            else
            {
                Indices = new uint[nv];
                for (int i = 0; i < nv; ++i) Indices[i] = (uint)i;
            }
            if (Indices.Length % 3 != 0) throw new AnchorRefusedException("anchor indices are not a multiple of 3");
            foreach (uint i in Indices)
                if (i >= nv) throw new AnchorRefusedException("anchor index " + i + " out of range for " + nv + " vertices");
            int faces = FaceCount = Indices.Length / 3;
            if (!AllFinite(AnchorVertices)) throw new AnchorRefusedException("anchor POSITION holds NaN or infinity");

            // profile, law, which anchors are stored
            string profile = Glb.Get(ext, "profile") as string;
            if (profile != "local" && profile != "games") throw new AnchorRefusedException("unknown profile " + profile);
            Games = profile == "games";
            if (Games && ext.ContainsKey("deformation"))
                throw new AnchorRefusedException("deformation must not be present with the games profile");
            if (!Games)
            {
                object law = Glb.Get(ext, "deformation") ?? "affine";
                if (!"affine".Equals(law) && !"rigid".Equals(law)) throw new AnchorRefusedException("unknown deformation " + law);
                Rigid = "rigid".Equals(law);
            }
            if (ext.ContainsKey("faceIndex") == ext.ContainsKey("faceCounts"))
                throw new AnchorRefusedException("exactly one of faceIndex and faceCounts must be present");
            bool derived = !Games && !ext.ContainsKey("barycentrics");
            if (derived)
                foreach (string k in Derived)
                    if (ext.ContainsKey(k))
                        throw new AnchorRefusedException("without barycentrics, normalOffset, localRotation and localScale must be absent");
            var props = new List<string> { ext.ContainsKey("faceIndex") ? "faceIndex" : "faceCounts" };
            if (!derived) props.AddRange(Games ? new[] { "barycentrics", "rho" } : Derived);
            var anchors = new Dictionary<string, Accessor>();
            foreach (string prop in props)
            {
                if (!ext.ContainsKey(prop)) throw new AnchorRefusedException(profile + " profile requires " + prop);
                Accessor a = d.Accessor(ext[prop], prop, "SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4");
                if (!Allowed(prop, a)) throw new AnchorRefusedException(prop + ": accessor layout not allowed");
                if (prop != "faceCounts" && a.Count != n)
                    throw new AnchorRefusedException(prop + " has " + a.Count + " elements, POSITION has " + n);
                anchors[prop] = a;
            }
            if (anchors.ContainsKey("faceCounts"))
            {
                uint[] counts = anchors["faceCounts"].UInts();
                if (counts.Length != faces) throw new AnchorRefusedException("faceCounts: one count per triangle expected");
                long total = 0;
                foreach (uint c in counts) total += c;
                if (total != n) throw new AnchorRefusedException("faceCounts does not sum to the " + n + " splats");
                Face = new uint[n];
                int s = 0;
                for (int f = 0; f < faces; ++f)
                    for (uint c = 0; c < counts[f]; ++c) Face[s++] = (uint)f;
            }
            else Face = anchors["faceIndex"].UInts();
            foreach (uint f in Face)
                if (f >= faces) throw new AnchorRefusedException("faceIndex " + f + " out of range for " + faces + " triangles");

            if (Games)
            {
                Bary = anchors["barycentrics"].Floats();
                Offset = anchors["rho"].Floats();
                if (!AllFinite(Bary) || !AllFinite(Offset)) throw new AnchorRefusedException("non-finite anchor data");
            }
            else if (derived)
            {
                CheckQuaternionsNonzero(RestRotation, "rest ROTATION (derived localRotation)");
                CheckNonnegative(RestScale, "rest SCALE (derived localScale)");
                NormalizeQuaternions(RestRotation);
                DeriveLocal();
                Scale = (float[])RestScale.Clone();
            }
            else
            {
                Bary = anchors["barycentrics"].Floats();
                Offset = anchors["normalOffset"].Floats();
                Rotation = anchors["localRotation"].Floats();
                Scale = anchors["localScale"].Floats();
                if (!AllFinite(Bary) || !AllFinite(Offset) || !AllFinite(Rotation) || !AllFinite(Scale))
                    throw new AnchorRefusedException("non-finite anchor data");
                CheckQuaternionsNonzero(Rotation, "localRotation");
                CheckNonnegative(Scale, "localScale");
            }
            NormalizeQuaternions(RestRotation);
            if (!Games)
            {
                NormalizeQuaternions(Rotation);   // every component type, FLOAT included
                PrepareRest();
            }
        }

        static void CheckQuaternionsNonzero(float[] q, string what)
        {
            for (int i = 0; i < q.Length / 4; ++i)
                if (q[4 * i] == 0 && q[4 * i + 1] == 0 && q[4 * i + 2] == 0 && q[4 * i + 3] == 0)
                    throw new AnchorRefusedException(what + " of splat " + i + " has length zero");
        }

        static void CheckNonnegative(float[] s, string what)
        {
            for (int i = 0; i < s.Length; ++i)
                if (s[i] < 0) throw new AnchorRefusedException(what + " of splat " + i / 3 + " is negative");
        }

        /// <summary>Unit quaternions, the norm taken in double (zero ones become identity).</summary>
        public static void NormalizeQuaternions(float[] q)
        {
            for (int i = 0; i < q.Length / 4; ++i)
            {
                double len = Math.Sqrt((double)q[4 * i] * q[4 * i] + (double)q[4 * i + 1] * q[4 * i + 1]
                                       + (double)q[4 * i + 2] * q[4 * i + 2] + (double)q[4 * i + 3] * q[4 * i + 3]);
                if (len > 0)
                    for (int j = 0; j < 4; ++j) q[4 * i + j] = (float)(q[4 * i + j] / len);
                else { q[4 * i] = q[4 * i + 1] = q[4 * i + 2] = 0; q[4 * i + 3] = 1; }
            }
        }

        /// <summary>The rest frame of face f in double (spec Triangle frames): columns t, b, n
        /// (row-major r), C_r = [[p, q], [0, h]] as c = (p, q, h); false when degenerate at rest.</summary>
        bool RestFrame(int f, double[] r, double[] c, out double area2)
        {
            var v = new double[3][];
            for (int k = 0; k < 3; ++k)
            {
                uint i = Indices[3 * f + k];
                v[k] = new double[] { AnchorVertices[3 * i], AnchorVertices[3 * i + 1], AnchorVertices[3 * i + 2] };
            }
            double[] e1 = new double[3], e2 = new double[3], e3 = new double[3];
            for (int k = 0; k < 3; ++k) { e1[k] = v[1][k] - v[0][k]; e2[k] = v[2][k] - v[0][k]; e3[k] = v[2][k] - v[1][k]; }
            double[] cr = { e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0] };
            double a = Math.Sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]);
            double s1 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
            double s2 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
            double s3 = e3[0] * e3[0] + e3[1] * e3[1] + e3[2] * e3[2];
            area2 = a;
            if (!(a > EpsDegenerate * Math.Max(Math.Max(s1, s2), s3))) return false;
            double p = Math.Sqrt(s1);
            double[] t = new double[3], n = new double[3];
            for (int k = 0; k < 3; ++k) { t[k] = e1[k] / p; n[k] = cr[k] / a; }
            double[] b = { n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2], n[0] * t[1] - n[1] * t[0] };
            for (int k = 0; k < 3; ++k) { r[3 * k] = t[k]; r[3 * k + 1] = b[k]; r[3 * k + 2] = n[k]; }
            c[0] = p;
            c[1] = e2[0] * t[0] + e2[1] * t[1] + e2[2] * t[2];
            c[2] = a / p;
            return true;
        }

        /// <summary>C_r^-1, a_r and 1/sqrt(a_r) of every face in double, stored as float
        /// (spec Outputs, precision and epsilons).</summary>
        void PrepareRest()
        {
            Rest = new RestFace[FaceCount];
            double[] r = new double[9], c = new double[3];
            for (int f = 0; f < FaceCount; ++f)
            {
                double area2;
                var rf = new RestFace { Inv0 = 1, Inv3 = 1, InvSqrtArea2 = 1 };
                rf.Regular = RestFrame(f, r, c, out area2);
                rf.Area2 = (float)area2;
                if (rf.Regular)
                {
                    rf.Inv0 = (float)(1 / c[0]);
                    rf.Inv1 = (float)(-c[1] / (c[0] * c[2]));
                    rf.Inv3 = (float)(1 / c[2]);
                    rf.InvSqrtArea2 = (float)(1 / Math.Sqrt(area2));
                }
                Rest[f] = rf;
            }
        }

        /// <summary>Derived local anchors (version 1.2), in double: (x, y, z) = R_r^T (mu - v0),
        /// b2 = y / h, b1 = (x - q b2) / p, d = z, q_l = conj(q_r) (x) q.</summary>
        void DeriveLocal()
        {
            int n = Count;
            Bary = new float[2 * n];
            Offset = new float[n];
            Rotation = new float[4 * n];
            double[] r = new double[9], c = new double[3], qr = new double[4];
            for (int s = 0; s < n; ++s)
            {
                int f = (int)Face[s];
                double area2;
                if (s == 0 || Face[s] != Face[s - 1])
                {
                    if (!RestFrame(f, r, c, out area2))
                        throw new AnchorRefusedException("splat " + s + " has derived anchors on face " + f + ", which is degenerate at rest");
                    MatrixToQuat(r, qr);
                }
                uint i0 = Indices[3 * f];
                double[] rel = new double[3];
                for (int k = 0; k < 3; ++k) rel[k] = (double)RestMeans[3 * s + k] - AnchorVertices[3 * i0 + k];
                double x = rel[0] * r[0] + rel[1] * r[3] + rel[2] * r[6];
                double y = rel[0] * r[1] + rel[1] * r[4] + rel[2] * r[7];
                double z = rel[0] * r[2] + rel[1] * r[5] + rel[2] * r[8];
                double b2 = y / c[2];
                Bary[2 * s] = (float)((x - c[1] * b2) / c[0]);
                Bary[2 * s + 1] = (float)b2;
                Offset[s] = (float)z;
                double qx = RestRotation[4 * s], qy = RestRotation[4 * s + 1], qz = RestRotation[4 * s + 2], qw = RestRotation[4 * s + 3];
                double len = Math.Sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
                qx /= len; qy /= len; qz /= len; qw /= len;
                double ax = -qr[0], ay = -qr[1], az = -qr[2], aw = qr[3];
                double ox = aw * qx + ax * qw + ay * qz - az * qy;
                double oy = aw * qy - ax * qz + ay * qw + az * qx;
                double oz = aw * qz + ax * qy - ay * qx + az * qw;
                double ow = aw * qw - ax * qx - ay * qy - az * qz;
                if (ow < 0) { ox = -ox; oy = -oy; oz = -oz; ow = -ow; }
                Rotation[4 * s] = (float)ox; Rotation[4 * s + 1] = (float)oy;
                Rotation[4 * s + 2] = (float)oz; Rotation[4 * s + 3] = (float)ow;
            }
        }

        /// <summary>Shepperd's quaternion (x, y, z, w; w >= 0) of a row-major rotation, double.</summary>
        static void MatrixToQuat(double[] m, double[] q)
        {
            double tr = m[0] + m[4] + m[8];
            double[] cand = { 1 + 2 * m[0] - tr, 1 + 2 * m[4] - tr, 1 + 2 * m[8] - tr, 1 + tr };
            int k = 0;
            for (int i = 1; i < 4; ++i) if (cand[i] > cand[k]) k = i;
            double s = 2 * Math.Sqrt(Math.Max(cand[k], 0));
            if (k == 3) { q[0] = (m[7] - m[5]) / s; q[1] = (m[2] - m[6]) / s; q[2] = (m[3] - m[1]) / s; q[3] = s / 4; }
            else if (k == 0) { q[0] = s / 4; q[1] = (m[1] + m[3]) / s; q[2] = (m[2] + m[6]) / s; q[3] = (m[7] - m[5]) / s; }
            else if (k == 1) { q[0] = (m[1] + m[3]) / s; q[1] = s / 4; q[2] = (m[5] + m[7]) / s; q[3] = (m[2] - m[6]) / s; }
            else { q[0] = (m[2] + m[6]) / s; q[1] = (m[5] + m[7]) / s; q[2] = s / 4; q[3] = (m[3] - m[1]) / s; }
            double len = Math.Sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
            if (q[3] < 0) len = -len;
            for (int i = 0; i < 4; ++i) q[i] /= len;
        }

        /// <summary>Skinned anchor vertices p' (scene space) in splat-local space, M^-1 p' in
        /// double; m is the splat node's global matrix, column-major (glTF node.matrix).</summary>
        public static void SplatLocal(float[] deformed, double[] m, float[] output)
        {
            double[] a = new double[9], inv = new double[9];
            for (int c = 0; c < 3; ++c) for (int r = 0; r < 3; ++r) a[3 * r + c] = m[4 * c + r];
            inv[0] = a[4] * a[8] - a[5] * a[7]; inv[1] = a[2] * a[7] - a[1] * a[8]; inv[2] = a[1] * a[5] - a[2] * a[4];
            inv[3] = a[5] * a[6] - a[3] * a[8]; inv[4] = a[0] * a[8] - a[2] * a[6]; inv[5] = a[2] * a[3] - a[0] * a[5];
            inv[6] = a[3] * a[7] - a[4] * a[6]; inv[7] = a[1] * a[6] - a[0] * a[7]; inv[8] = a[0] * a[4] - a[1] * a[3];
            double det = a[0] * inv[0] + a[1] * inv[3] + a[2] * inv[6];
            if (det == 0 || double.IsNaN(det) || double.IsInfinity(det))
                throw new ArgumentException("the splat node's matrix is singular or not finite");
            for (int i = 0; i < 9; ++i) inv[i] /= det;
            for (int i = 0; i < deformed.Length / 3; ++i)
            {
                double x = deformed[3 * i] - m[12], y = deformed[3 * i + 1] - m[13], z = deformed[3 * i + 2] - m[14];
                for (int r = 0; r < 3; ++r)
                    output[3 * i + r] = (float)(inv[3 * r] * x + inv[3 * r + 1] * y + inv[3 * r + 2] * z);
            }
        }
    }
}
