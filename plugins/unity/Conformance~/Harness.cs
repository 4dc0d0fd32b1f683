// Harness.cs -- the conformance harness of the C# core (spec/conformance.md): for every case of
// the numbers level of an exported suite, import asset.glb with AnchoredAsset (or write
// `refused`), dump the rest pose, remap every pose with Remapper and dump means and
// covariances, then the opacity and SH after the last pose. Not part of the Unity package
// (a folder ending in ~ is ignored by Unity). Build and run (tests/csharp_core.py does):
//   mcs -out:harness.exe ../Runtime/*.cs Harness.cs && mono harness.exe SUITE RESULTS [--rotation-scale]
using System;
using System.Collections.Generic;
using System.IO;
using System.Text;
using Gsverse.MeshAnchor;

static class Harness
{
    /// <summary>The most bytes one Remapper.Apply allocated (after a case's poses).</summary>
    static long frameAllocations;

    static Dictionary<string, object> ReadJson(string path)
    {
        return (Dictionary<string, object>)Json.Parse(File.ReadAllText(path, Encoding.UTF8));
    }

    static void Dump(string folder, string stem, float[] values)
    {
        var bytes = new byte[4 * values.Length];
        Buffer.BlockCopy(values, 0, bytes, 0, bytes.Length);   // little-endian hosts only
        File.WriteAllBytes(Path.Combine(folder, stem + ".f32"), bytes);
    }

    static float[] ReadFloats(string path)
    {
        byte[] bytes = File.ReadAllBytes(path);
        var out_ = new float[bytes.Length / 4];
        Buffer.BlockCopy(bytes, 0, out_, 0, out_.Length * 4);
        return out_;
    }

    static string Runtime()
    {
        Type mono = Type.GetType("Mono.Runtime");
        var name = mono == null ? null : mono.GetMethod("GetDisplayName",
            System.Reflection.BindingFlags.NonPublic | System.Reflection.BindingFlags.Static);
        return name == null ? "CLR " + Environment.Version : "Mono " + name.Invoke(null, null);
    }

    /// <summary>--rotation-scale: dump Remapper's rotations and scales instead of covariances.</summary>
    static bool rotationScale;

    static void RunCase(string folder, Dictionary<string, object> manifest, string output)
    {
        var files = Glb.Obj(manifest["files"]);
        AnchoredAsset asset;
        try
        {
            asset = AnchoredAsset.Read(File.ReadAllBytes(Path.Combine(folder, (string)files["asset"])));
        }
        catch (AnchorRefusedException e)
        {
            File.WriteAllText(Path.Combine(output, "refused"), e.Message + "\n");
            return;
        }
        Dump(output, "rest.means", asset.RestMeans);
        Dump(output, "rest.cov", Remapper.RestCovariances(asset));
        Dump(output, "rest.opacity", asset.Opacity);
        Dump(output, "rest.sh", asset.Sh);
        var remapper = new Remapper(asset, rotationScale);
        bool rig = "rig".Equals(manifest["kind"]);
        var poses = Glb.List(files, rig ? "deformed" : "poses");
        var vertices = new float[asset.AnchorVertices.Length];
        for (int p = 0; p < poses.Count; ++p)
        {
            float[] pose = ReadFloats(Path.Combine(folder, (string)poses[p]));
            var rigInfo = Glb.Obj(Glb.Get(manifest, "rig"));
            if (rig && true.Equals(Glb.Get(rigInfo, "skinned")))
            {
                var m = new double[16];
                var list = Glb.List(rigInfo, "splat_node_matrix");
                for (int k = 0; k < 16; ++k) m[k] = (double)list[k];
                AnchoredAsset.SplatLocal(pose, m, vertices);
            }
            else Array.Copy(pose, vertices, Math.Min(pose.Length, vertices.Length));
            if (pose.Length != vertices.Length) throw new InvalidDataException("pose " + p + " has the wrong vertex count");
            remapper.Apply(vertices);
            string stem = "pose_" + p.ToString("D3");
            Dump(output, stem + ".means", remapper.Means);
            if (rotationScale)
            {
                Dump(output, stem + ".rotation", remapper.Rotations);
                Dump(output, stem + ".scale", remapper.Scales);
            }
            else Dump(output, stem + ".cov", remapper.Cov);
        }
        if (poses.Count > 0)
        {
            // one more frame, measured: Remapper.Apply allocates nothing
            long before = GC.GetAllocatedBytesForCurrentThread();
            remapper.Apply(vertices);
            frameAllocations = Math.Max(frameAllocations, GC.GetAllocatedBytesForCurrentThread() - before);
        }
        Dump(output, "posed.opacity", asset.Opacity);
        Dump(output, "posed.sh", asset.Sh);
    }

    static int Main(string[] args)
    {
        rotationScale = args.Length == 3 && args[2] == "--rotation-scale";
        if (args.Length != 2 && !rotationScale)
        {
            Console.Error.WriteLine("usage: mono harness.exe SUITE RESULTS [--rotation-scale]");
            return 2;
        }
        try
        {
            return Run(args[0], args[1]);
        }
        catch (Exception e) when (e is IOException || e is UnauthorizedAccessException || e is FormatException
                                  || e is InvalidCastException || e is KeyNotFoundException)
        {
            // a missing or unreadable suite: one line, no trace (each case's own failures are
            // recorded in its folder by Run)
            Console.Error.WriteLine("harness: error: " + e.Message);
            return 1;
        }
    }

    static int Run(string suite, string results)
    {
        Directory.CreateDirectory(results);
        int count = 0;
        foreach (object entry in Glb.List(ReadJson(Path.Combine(suite, "suite.json")), "cases"))
        {
            var e = Glb.Obj(entry);
            string kind = (string)e["kind"];
            if (kind != "remap" && kind != "rig" && kind != "invalid") continue;   // not the render level
            string folder = Path.Combine(suite, (string)e["path"]);
            var manifest = ReadJson(Path.Combine(folder, "case.json"));
            string output = Path.Combine(results, (string)manifest["id"]);
            Directory.CreateDirectory(output);
            try
            {
                RunCase(folder, manifest, output);
            }
            catch (Exception err)   // this case's failure is recorded, the run goes on
            {
                File.WriteAllText(Path.Combine(output, "error"), err.GetType().Name + ": " + err.Message + "\n");
            }
            count++;
        }
        // the core does not decode SPZ-compressed rest poses: declared, so that the check reports
        // those cases "unsupported" (spec/conformance.md, Optional features)
        File.WriteAllText(Path.Combine(results, "harness.json"),
            "{\n \"name\": \"gsverse C# core (plugins/unity/Runtime)\",\n \"runtime\": \"" + Runtime().Replace("\"", "'")
            + "\",\n \"precision\": \"float32 (rest quantities in double)\",\n \"outputs\": \""
            + (rotationScale ? "rotation + scale" : "covariance") + "\",\n \"bytes_allocated_per_frame\": "
            + frameAllocations + ",\n \"unsupported\": [\"encoding:spz\"]\n}\n");
        Console.WriteLine("gsverse C# core: " + count + " cases -> " + results);
        return 0;
    }
}
